"""izb's bad input: a sample count not in the list, a grid size not a power of two or over
8192, the reference pattern at a count its square grid cannot give, and lists over the memory
budget are exit 2 with one line naming the file and the key, before anything is built or
written."""

from __future__ import annotations

import pytest
import yaml

from harness import cli
from techniques.izb import izb


def experiment(tmp_path, settings: dict, scene_file) -> tuple[str, str]:
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump({"scene_file": str(scene_file), "scenes": ["box_plane"],
                                    "frames": 1, "warmup": 0,
                                    "techniques": {"izb": {"set": settings}}}))
    return str(path), str(tmp_path / "out")


@pytest.mark.parametrize("settings,says", [
    ({"samples": 3}, "izb.samples: Input should be 1, 4, 8, 16 or 32"),
    ({"res": 1000}, "izb.res: must be a power of two, got 1000"),
    ({"res": 16384}, "izb.res: Input should be less than or equal to 8192"),
    ({"samples": 8, "pattern": "reference", "surface": "plane"},
     "izb.pattern: reference needs samples 1, 4 or 16"),
    ({"pattern": "reference"}, "izb.pattern: reference needs surface: plane"),
    ({"fit": "tight"}, "izb.fit: Input should be 'plain' or 'view'"),
])
def test_bad_parameters_are_exit_2_naming_file_and_key(settings, says, tmp_path,
                                                       small_scene_file, capsys):
    """Catches a Params that lets any sample count through (the mask has 32 bits), a grid
    size the raster's texel arithmetic does not assume (any integer), and the reference
    pattern at 8 or 32 samples (Mitsuba's stratified grid is square: it would fail in
    prepare, a run's error row)."""
    path, out = experiment(tmp_path, settings, small_scene_file("box_plane"))
    code = cli.main(["run", path, "--out", out, "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert path in err and says in err, err


def test_lists_over_the_budget_are_refused_before_anything_is_built(tmp_path, small_scene_file,
                                                                    capsys, monkeypatch):
    """box_plane at 64 x 48 with 32 samples and a 4096^2 grid: 64 x 48 x (32 x 20 + 4 + 40)
    + 4096^2 x 4 bytes = 66.1 MiB of lists (computed here, independently of bound_bytes); with
    budget_mib 66 the plan refuses it, exit 2, one line naming the key and the budget, and
    nothing is allocated (prepare never called) or written. Catches a budget checked in
    prepare only (a run's error row, exit 1) or not at all."""
    expected = 64 * 48 * (32 * (16 + 4) + 4 + 4 + 36) + 4096 ** 2 * 4
    assert 66 * 2**20 < expected < 67 * 2**20
    monkeypatch.setattr(izb.IrregularZBuffer, "prepare",
                        lambda *a: pytest.fail("prepare ran"))
    path, out = experiment(tmp_path, {"samples": 32, "res": 4096, "budget_mib": 66},
                           small_scene_file("box_plane"))
    code = cli.main(["run", path, "--out", out, "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert path in err and "izb.budget_mib" in err and "over the budget of 66 MiB" in err, err
    assert not (tmp_path / "out").exists()
