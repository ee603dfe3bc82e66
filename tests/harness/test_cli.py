"""The command line end to end: run, results, arrays, report; failures and resumption."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
from helpers import result_rows, run_cli

from harness import cli
from harness.technique import registry
from harness.technique import Technique, TechniqueParams

REQUIRED = ("scene technique params width height map_res time_ms time_ms_min time_ms_max frames "
            "frags_scene frags_shadow overdraw mem_bytes fetches_per_px mae rmse wrong_pct "
            "edge_mae ssim psnr flip levels nonfinite renderer status error array").split()
METRICS = "mae rmse wrong_pct edge_mae ssim psnr levels time_ms".split()


def test_run_end_to_end(small_scene_file, tmp_path, gl_context, capsys):
    scene_file = small_scene_file()
    out = tmp_path / "run"
    exe = Path(sys.executable).with_name("shadowbench")
    proc = subprocess.run([str(exe), "run", "--scene-file", str(scene_file),
                           "--techniques", "sm,pcf", "--set", "pcf.k=4", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    rows = result_rows(out)
    assert len(rows) == 4
    for r in rows:
        for column in REQUIRED:
            assert column in r
        assert r["status"] == "ok" and r["error"] == ""
        for m in METRICS:
            assert math.isfinite(float(r[m])), (m, r[m])
        assert (r["flip"] != "") == (r["scene"] == "sphere_plane")  # only where shading asked
        if r["technique"] == "pcf":
            assert json.loads(r["params"])["k"] == 4
        with np.load(out / r["array"]) as z:
            assert z["visibility"].shape == (48, 64) and z["visibility"].dtype == np.float32
            assert z["covered"].dtype == bool
    assert (out / "arrays/box_plane/64x48/reference-16spp-seed0.npz").is_file()
    assert {r["reference_array"] for r in rows if r["scene"] == "box_plane"} == {
        "arrays/box_plane/64x48/reference-16spp-seed0.npz"}
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["gl"]["renderer"] and manifest["finished"]
    assert "box_plane" in proc.stderr  # progress names the scene

    report = subprocess.run([str(exe), "report", str(out)], capture_output=True, text=True,
                            timeout=300)
    assert report.returncode == 0, report.stderr
    index = out / "index.html"
    assert index.is_file() and "sphere_plane" in index.read_text()

    code, err = run_cli(["run", "--scene-file", scene_file, "--techniques", "sm,pcf", "--set",
                         "pcf.k=4", "--out", out, "--quiet"], capsys)  # in this process
    assert code == 0, err
    assert [r["run_id"] for r in result_rows(out)] == [r["run_id"] for r in rows]  # nothing redone


class Broken(Technique):
    """A technique whose shader does not exist.

    ======  =======  =======  =====
    Name    Meaning  Default  Range
    ======  =======  =======  =====
    ======  =======  =======  =====
    """

    name = "broken"
    summary = "fails on purpose"
    paper = "none"

    class Params(TechniqueParams):
        pass

    def prepare(self, frame):
        self.shader(__file__, "fullscreen.vert.glsl", "does-not-exist.frag.glsl")


def test_a_failing_technique_writes_an_error_row_and_exit_1(small_scene_file, tmp_path,
                                                            monkeypatch, gl_context, capsys):
    scene_file = small_scene_file()
    found = dict(registry.techniques())
    found["broken"] = Broken
    monkeypatch.setattr(registry, "techniques", lambda: found)
    out = tmp_path / "run"
    code = cli.main(["run", "--scene-file", str(scene_file), "--scenes", "box_plane",
                     "--techniques", "broken,sm", "--out", str(out), "--quiet"])
    assert code == 1
    rows = {r["technique"]: r for r in result_rows(out)}
    assert rows["sm"]["status"] == "ok"
    assert rows["broken"]["status"] == "error"
    assert "does-not-exist.frag.glsl" in rows["broken"]["error"]
    assert "\n" not in rows["broken"]["error"]
    assert "failed: box_plane broken" in capsys.readouterr().out  # the summary: stdout


def test_list_names_techniques_and_scenes(capsys):
    assert cli.main(["list"]) == 0
    text = capsys.readouterr().out
    assert "sm " in text and "pcf " in text and "box_plane" in text and "res_factor" in text


def test_reference_command(small_scene_file, tmp_path, capsys):
    scene_file = small_scene_file()
    code = cli.main(["reference", "--scene", "box_plane", "--scene-file", str(scene_file),
                     "--out", str(tmp_path / "ref"), "--samples", "4"])
    assert code == 0
    assert (tmp_path / "ref/arrays/box_plane/64x48/reference-4spp-seed0.npz").is_file()
    assert "llvm_ad_rgb" in capsys.readouterr().out


def test_list_shows_readable_defaults_and_ranges(capsys):
    assert cli.main(["list"]) == 0
    lines = capsys.readouterr().out.splitlines()

    def param_line(technique, param):
        start = next(i for i, line in enumerate(lines) if line.split()[:1] == [technique])
        return next(line for line in lines[start + 1:] if line.split()[:1] == [param])

    assert "grid | jitter" in param_line("pcf", "sampling")
    assert "square" in param_line("pcf", "k")
    assert ">= 16" in param_line("pcf", "res") and "<= 8192" in param_line("pcf", "res")
    assert "1 | 2 | 3 | 4" in param_line("mdsm", "n")
    # each technique's quality knobs, with the values its curve walks
    for name, cls in registry.techniques().items():
        start = next(i for i, line in enumerate(lines) if line.split()[:1] == [name])
        end = next((i for i, line in enumerate(lines[start + 1:], start + 1)
                    if not line.startswith("      ")), len(lines))
        shown = {line.split(":")[0].split()[-1]: line.split(": ")[1] for line in lines[start:end]
                 if line.split()[:2] == ["quality", "knob"]}
        assert shown == {k: ", ".join(str(v) for v in values)
                         for k, values in cls.quality_knobs.items()}, name
    text = "\n".join(lines)
    assert "function" not in text and "object at 0x" not in text
    assert "AfterValidator" not in text and "Literal" not in text
