"""A technique from outside the project (examples/plugin), installed as a user would install it
and found through the entry point alone."""

import csv
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import ROOT

PLUGIN = ROOT / "examples" / "plugin"
SHADOWBENCH = Path(sys.executable).with_name("shadowbench")

EXPERIMENT = """\
scenes: [box_plane]
techniques: {sm: {}, hwpcf: {}}
resolutions: [[128, 128]]
frames: 1
warmup: 0
"""


@pytest.fixture(scope="module")
def hwpcf_env(plugin_env):
    """A shell's environment with examples/plugin installed (conftest's ``plugin_env``)."""
    return plugin_env(PLUGIN)


def test_the_installed_plugin_is_listed_with_its_parameters(hwpcf_env, tmp_path):
    listed = subprocess.run([str(SHADOWBENCH), "list", "--scene-file", str(ROOT / "scenes.yaml")],
                            env=hwpcf_env, cwd=tmp_path, capture_output=True, text=True,
                            timeout=120)
    assert listed.returncode == 0, listed.stderr
    lines = listed.stdout.splitlines()
    start = next(i for i, line in enumerate(lines) if line.split()[:1] == ["hwpcf"])
    block = "\n".join(lines[start:start + 5])
    for parameter in ("res", "normal_offset", "bias", "quality knob res: 256, 1024, 4096"):
        assert parameter in block, block
    # without the folder on the path there is no such technique: the entry point found it
    bare = subprocess.run([str(SHADOWBENCH), "list", "--scene-file", str(ROOT / "scenes.yaml")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert bare.returncode == 0, bare.stderr
    assert "hwpcf" not in bare.stdout


def test_a_run_scores_the_plugin_beside_sm(hwpcf_env, tmp_path):
    """box_plane at 128 px with map 1024: a map texel is about 1/6 of a pixel, so hwpcf's
    one-texel ramp at an edge lies inside the edge pixel and both it and sm answer the pixel
    centre's visibility. Their error is then what any point sample misses of the reference's
    pixel-area average: hwpcf's mae within 20% of sm's (measured: 0.00089 and 0.00094), its
    edge_mae within 10% of edge_floor (the reference rounded to 0/1: 0.0298 against 0.0313).
    Fractional V in the edge band (levels > 2) shows the GL_LINEAR comparison acting: with
    GL_NEAREST the map gives sm's two levels. The normal offset keeps the plane free of acne
    at the defaults (acne_pct 0). Catches the comparison unfiltered (GL_NEAREST: 2 levels) and
    the normal offset lost (0 texels: acne, mae 0.18)."""
    experiment = tmp_path / "plugin.yaml"
    experiment.write_text(EXPERIMENT)
    out = tmp_path / "out"
    run = subprocess.run([str(SHADOWBENCH), "run", str(experiment), "--scene-file",
                          str(ROOT / "scenes.yaml"), "--out", str(out)],
                         env=hwpcf_env, cwd=tmp_path, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    with (out / "results.csv").open() as f:
        rows = {r["technique"]: r for r in csv.DictReader(f)}
    assert set(rows) == {"sm", "hwpcf"}
    hwpcf, sm = rows["hwpcf"], rows["sm"]
    assert hwpcf["status"] == "ok" and hwpcf["error"] == ""
    assert float(hwpcf["mae"]) == pytest.approx(float(sm["mae"]), rel=0.2)
    assert float(hwpcf["edge_mae"]) == pytest.approx(float(hwpcf["edge_floor"]), rel=0.1)
    assert int(hwpcf["levels"]) > 2 and int(sm["levels"]) == 2
    assert float(hwpcf["acne_pct"]) == 0.0
    assert int(hwpcf["fetches_per_px"]) == 4
    assert int(hwpcf["mem_bytes"]) == 1024 * 1024 * 4
