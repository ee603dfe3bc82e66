"""A run's stored edge metrics are those of its stored arrays: edge_mae, acne_pct and leak_pct
recomputed by harness.metrics, with its default edge band, from the run's V and compared pixels
and the scene's reference as the run folder keeps them. Catches the band the runs are scored
with narrowed (score.py's FrameTruth asking edge_band for 1 pixel instead of the default 2)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from helpers import result_rows, scene_with, write_scenes

from harness import cli, results
from harness.truth import metrics

EDGE_METRICS = {"edge_mae": metrics.edge_mae, "acne_pct": metrics.acne_pct,
                "leak_pct": metrics.leak_pct}
# sm without bias: acne over the lit plane; with a bias past the box's height: its shadow
# leaks. A box of 4 x 4 at 64 x 64 pixels, so that shadow has pixels farther than the band
# from its edges.
SM_SETTINGS = [{"bias": 0, "slope_bias": 0}, {"bias": 5}]
SCENE = scene_with(resolution=[64, 64], objects__1__size=[4, 4, 1])


def test_stored_edge_metrics_are_the_stored_arrays_scored_with_the_default_band(tmp_path,
                                                                                  gl_context):
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({
        "techniques": {"sm": [{"set": s} for s in SM_SETTINGS]}, "frames": 1, "warmup": 0,
        "reference": {"samples": 1}}))
    out = tmp_path / "out"
    assert cli.main(["run", str(experiment), "--scene-file",
                     str(write_scenes(tmp_path, {"s": SCENE})), "--out", str(out),
                     "--quiet"]) == 0
    rows = result_rows(out)
    assert [row["status"] for row in rows] == ["ok"] * len(SM_SETTINGS)
    width_shows = set()  # the metrics that a 1-pixel band would have changed in some run
    for row in rows:
        run = np.load(results.inside(out, row["array"]))
        reference = np.load(results.inside(out, row["reference_array"]))
        v, ref, compared = run["visibility"], reference["visibility"], run["compared"]
        recomputed = {name: metric(v, ref, mask=compared) for name, metric in EDGE_METRICS.items()}
        stored = {name: float(row[name]) for name in EDGE_METRICS}
        assert stored == pytest.approx(recomputed, rel=1e-12), row["params"]
        width_shows |= {name for name, metric in EDGE_METRICS.items()
                        if metric(v, ref, mask=compared, width=1) != recomputed[name]}
    assert width_shows == set(EDGE_METRICS)
