"""The EGL backend (Mesa's surfaceless llvmpipe here; the GPU on an NVIDIA machine)."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.gl.measure import default_timer

EXE = str(Path(sys.executable).with_name("shadowbench"))


def _arrays(out):
    with (out / "results.csv").open() as f:
        rows = {r["run_id"]: r for r in csv.DictReader(f)}
    return {k: np.load(out / r["array"])["visibility"] for k, r in rows.items()}, rows


def test_egl_platform_renders_the_same_visibility(small_scene_file, tmp_path):
    scene_file = small_scene_file()
    runs = {}
    for platform in ("osmesa", "egl"):
        out = tmp_path / platform
        proc = subprocess.run([EXE, "run", "--scene-file", str(scene_file), "--quiet",
                               "--techniques", "sm,pcf,sv", "--platform", platform,
                               "--frames", "1", "--warmup", "0",  # V, not timing
                               "--out", str(out)], capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr
        runs[platform] = _arrays(out)
        manifest = json.loads((out / "manifest.json").read_text())
        assert manifest["gl"]["platform"] == platform
        assert manifest["gl"]["timer"] == default_timer(manifest["gl"]["renderer"])
    (a, _), (b, rows) = runs["osmesa"], runs["egl"]
    assert a.keys() == b.keys() and len(a) == 6
    for run_id in a:  # both are Mesa's llvmpipe: the same pixels
        assert np.array_equal(a[run_id], b[run_id]), rows[run_id]["technique"]


def test_timer_choice():
    assert default_timer("llvmpipe (LLVM 15.0.6, 256 bits)") == "clock"
    assert default_timer("NVIDIA H100 80GB HBM3/PCIe/SSE2") == "query"


def test_timer_queries_measure_passes_on_egl():
    """GL_TIME_ELAPSED through ctypes, on Mesa's EGL (where the query interface loads)."""
    code = (
        "from harness.gl.context import get_context; get_context('egl')\n"
        "from harness.gl.measure import PassMeter\n"
        "from harness.gl.framebuffer import Framebuffer\n"
        "fb = Framebuffer(256, 256)\n"
        "m = PassMeter('query')\n"
        "for i in range(6):\n"
        "    m.new_frame(i >= 1)\n"
        "    with m.measure('clear'): fb.clear((1, 1, 1, 1))\n"
        "print(m.passes()[0].ms)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, env={"SHADOWBENCH_GL": "egl", "PATH": "/usr/bin"})
    assert proc.returncode == 0, proc.stderr
    ms = float(proc.stdout.strip().splitlines()[-1])
    assert 0 < ms < 1000


def test_missing_platform_library_names_the_package(monkeypatch, gl_context):
    from pyrender.platforms.osmesa import OSMesaPlatform

    from harness.gl import context

    def missing(self):
        raise ImportError("Unable to load OpenGL library: libOSMesa.so.8: cannot open")

    monkeypatch.setattr(OSMesaPlatform, "init_context", missing)
    with pytest.raises(context.BackendError) as e:
        context.GLContext("osmesa")
    assert "libosmesa6" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(context.BackendError, match="unknown GL platform"):
        context.GLContext("vulkan")
    gl_context.make_current()
