"""A view with no surface in it: SDSM's depth reduction over no covered pixel is empty, and csm
falls back to fit frustum's range (here, the scene's box wholly behind the camera, the camera's
near and far), as documented, with finite matrices.
Catches the empty range read as NaN (the reduction's start values decode to NaN, and NaN > NaN
is false, so ``empty`` said no): every cascade's view and projection had NaNs, and the row read
ok with nonfinite=16 (seen failing)."""

from __future__ import annotations

import numpy as np
import yaml

from harness.scene import load_scene

# the camera looks up, away from the plane and the box: no pixel covered
SCENE = {"resolution": [64, 64], "camera": {"position": [0, -6, 4], "target": [0, -12, 8]},
         "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
         "objects": [{"shape": "plane", "size": [10, 10]},
                     {"shape": "box", "size": [1, 1, 1], "translate": [0, 0, 1.5]}]}


def test_sdsm_over_an_empty_view_fits_the_frustum(tmp_path, evaluate, monkeypatch):
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path / "cache"))
    (tmp_path / "scenes.yaml").write_text(yaml.safe_dump({"scenes": {"e": SCENE}}))
    scene = load_scene("e", tmp_path / "scenes.yaml")
    sdsm = evaluate(scene, "csm", {"fit": "sdsm"}, frames=1, warmup=0, samples=1)
    frustum = evaluate(scene, "csm", {"fit": "frustum"}, frames=1, warmup=0, samples=1)
    assert not sdsm.frame_arrays.covered.any()
    for result in (sdsm, frustum):
        assert result.row["status"] == "ok" and result.row["nonfinite"] == 0, result.row
    splits = [sdsm.row[f"split_{i}"] for i in range(5)]
    assert np.isfinite(splits).all()
    assert splits == [frustum.row[f"split_{i}"] for i in range(5)]
    assert splits[0] == 0.1 and splits[-1] == 100.0  # the camera's near and far
