"""The dashboard: its pure helpers on hand-made data, then a page built from a real small run."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from harness import registry, report, results
from harness.cli import main as shadowbench

ROOT = Path(__file__).resolve().parent.parent
SMALL = [[64, 64], [96, 96]]
# Two scenes: one shadow-only (directional light) and one shaded (spot light, so flip exists).
SCENES = ["box_plane", "sphere_plane"]


def make_run_dir(out: Path) -> Path:
    """A small real run directory: an sm and pcf parameter grid, then every registered technique
    at its defaults, on two scenes at two resolutions, plus one failed row of a technique this
    install does not know (as results copied from elsewhere would have)."""
    common = {"scenes": SCENES, "resolutions": SMALL, "frames": 1, "warmup": 0,
              "reference": {"samples": 4}}
    grid = {**common, "techniques": {"sm": {"product": {"res": [256, 1024]}},
                                     "pcf": {"product": {"k": [4, 16]}}}}
    every = {**common, "techniques": "all"}
    for name, experiment in (("grid", grid), ("every", every)):
        path = out.parent / f"{out.name}-{name}.yaml"
        path.write_text(json.dumps(experiment))
        code = shadowbench(["run", str(path), "--scene-file", str(ROOT / "scenes.yaml"),
                            "--out", str(out), "--quiet"])
        assert code in (0, 1)
    rows = results.read_rows(out)
    rows.append({**rows[0], "run_id": "0" * 16, "technique": "broken_example",
                 "params": json.dumps({"res": 64}), "status": "error",
                 "error": "RuntimeError: shader failed to link", "time_ms": "", "mae": "",
                 "edge_mae": "", "wrong_pct": "", "array": ""})
    results.write_rows(out, rows)
    return out


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory, gl_context):
    return make_run_dir(tmp_path_factory.mktemp("dashboard") / "run")


@pytest.fixture(scope="module")
def built(run_dir):
    index = report.build_report(run_dir)
    return index, index.read_text()


# --- helpers on hand-made data ------------------------------------------------------------------

def test_pareto_front_keeps_only_runs_nothing_beats():
    times = [1.0, 2.0, 3.0, 4.0, 5.0, 2.0]
    errors = [5.0, 3.0, 4.0, 1.0, 2.0, 3.5]
    # (3, 4) is beaten by (2, 3); (5, 2) by (4, 1); (2, 3.5) by (2, 3)
    assert report.pareto_front(times, errors) == [0, 1, 3]


def test_edge_crop_lies_on_the_shadow_edge():
    ref = np.ones((128, 128), np.float32)
    ref[:, :40] = 0.0  # a vertical shadow boundary between columns 39 and 40
    covered = np.ones_like(ref, bool)
    r, c, size = report.edge_crop(ref, covered)
    assert size == 24  # an eighth of 128 is 16, below the 24 px minimum
    assert 0 <= r and r + size <= 128 and c < 40 < c + size
    assert report.edge_crop(np.ones((64, 64)), np.ones((64, 64), bool)) is None


def _rows(**columns) -> pd.DataFrame:
    n = len(next(iter(columns.values())))
    base = {"scene": ["s"] * n, "width": [64] * n, "height": [64] * n,
            "params": [{"i": i} for i in range(n)], "status": ["ok"] * n,
            "nonfinite": [0.0] * n, "v_min": [0.0] * n, "v_max": [1.0] * n,
            "wrong_pct": [1.0] * n, "error": [""] * n}
    return pd.DataFrame({**base, **columns})


def test_stability_marks_failures_nonfinite_and_v_out_of_range():
    rows = _rows(technique=["a", "a", "b", "c", "d", "e"],
                 status=["ok", "ok", "error", "ok", "ok", "skipped"],
                 error=["", "", "boom", "", "", "not applicable"],
                 nonfinite=[0, 0, np.nan, 3, 0, np.nan], v_min=[0, 0, np.nan, 0, -0.1, np.nan],
                 v_max=[1, 1, np.nan, 1, 1, np.nan], wrong_pct=[0.5, 2.5, np.nan, 1, 1, np.nan])
    cells = report.stability_cells(rows)
    assert not cells[("s", "a")]["fails"] and cells[("s", "a")]["worst_wrong_pct"] == 2.5
    assert cells[("s", "b")]["fails"] and cells[("s", "b")]["first_error"] == "boom"
    assert cells[("s", "c")]["fails"] and cells[("s", "c")]["nonfinite"] == 1
    assert cells[("s", "d")]["fails"] and cells[("s", "d")]["out_of_range"] == 1
    assert not cells[("s", "e")]["fails"] and cells[("s", "e")]["skipped"] == 1
    page = report.stability_table(rows)
    assert page.count('class="fail"') == 3 and page.count('class="pass"') == 1


def test_cheapest_run_within_each_budget():
    rows = _rows(technique=["a", "b", "c", "d"], time_ms=[1.0, 2.0, 4.0, 0.5],
                 edge_mae=[0.3, 0.15, 0.01, np.nan], wrong_pct=[3.0, 1.0, 0.05, 0.0],
                 status=["ok", "ok", "ok", "error"])
    cheapest = report.cheapest_runs(rows)
    pick = {(m, b): None if r is None else r["technique"] for (m, b, _), r in cheapest.items()}
    # the failed run d is fastest and "meets" every wrong_pct budget, but it failed
    assert pick[("edge_mae", 0.02)] == "c" and pick[("edge_mae", 0.2)] == "b"
    assert pick[("edge_mae", 0.3)] == "a" and pick[("wrong_pct", 0.1)] == "c"
    assert pick[("wrong_pct", 1.0)] == "b" and pick[("wrong_pct", 5.0)] == "a"
    assert report.cheapest_runs(_rows(technique=["a"], time_ms=[1.0], edge_mae=[0.5],
                                      wrong_pct=[50.0]))[("edge_mae", 0.3, (64, 64))] is None


def test_a_rerun_supersedes_the_older_row_of_the_same_run():
    rows = _rows(technique=["a", "a", "b"], params=[{"k": 1}, {"k": 1}, {"k": 1}],
                 time_ms=[5.0, 3.0, 1.0])
    current = report.current_rows(rows)
    assert sorted(current["time_ms"]) == [1.0, 3.0]


# --- a page built from a real run ---------------------------------------------------------------

def test_page_embeds_plotly_once_and_loads_nothing_from_the_network(built):
    _, page = built
    assert page.count("plotly.js v") == 1  # the library's licence header
    head, _library, rest = re.split(r"<script[^>]*>/\*\*\s*\* plotly\.js v.*?</script>", page,
                                   maxsplit=1, flags=re.DOTALL) + [""]
    outside = head + rest
    assert not re.search(r"""(src|href)=["']https?:""", outside)
    assert "cdn.plot.ly" not in outside and "<script src" not in outside


def test_every_scene_has_its_plots_tables_and_images(built, run_dir):
    index, page = built
    df = report.current_rows(results.load(run_dir))
    for scene in SCENES:
        assert f'id="{scene}-cost-accuracy"' in page and f'id="{scene}-costs"' in page
    sources = re.findall(r'<img src="([^"]+)"', page)
    for src in sources:
        assert (index.parent / src).is_file(), src
    # the image grid: at the larger resolution, every technique with an ok run has V, error, crop
    for scene in SCENES:
        ok = df[(df["scene"] == scene) & (df["status"] == "ok") & (df["width"] == 96)]
        assert f"images/{scene}/96x96/reference.png" in sources
        for technique in ok["technique"].unique():
            mine = [s for s in sources if f"images/{scene}/96x96/{technique}-" in s
                    and "-map-" not in s]
            assert len(mine) == 3, (scene, technique, mine)
    assert "broken_example" in page and "shader failed to link" in page


def test_image_grid_shows_each_technique_at_its_defaults(built, run_dir):
    _, page = built
    df = report.current_rows(results.load(run_dir))
    sm = df[(df["technique"] == "sm") & (df["scene"] == "box_plane") & (df["width"] == 96)]
    assert len(sm) == 2  # the grid's res 256 and 1024 (the default)
    default = registry.get("sm").Params().model_dump(mode="json")
    at_default = sm[sm["params"].map(lambda p: p == default)]
    other = sm[sm["params"].map(lambda p: p != default)]
    assert len(at_default) == 1 and len(other) == 1
    assert Path(at_default["array"].iloc[0]).stem + ".png" in page
    assert Path(other["array"].iloc[0]).stem + ".png" not in page


def test_scatter_offers_flip_only_where_the_scene_is_shaded(run_dir):
    df = report.current_rows(results.load(run_dir))
    colours = report._colours(df["technique"].unique())
    for scene, shaded in (("box_plane", False), ("sphere_plane", True)):
        fig = report.cost_accuracy_figure(df[df["scene"] == scene], colours)
        labels = [b.label for b in fig.layout.updatemenus[0].buttons]
        assert labels[:3] == ["edge_mae", "mae", "wrong_pct"]
        assert ("flip" in labels) == shaded
        # one marker per ok run for the first metric, and a Pareto front per resolution
        shown = [t for t in fig.data if t.visible]
        markers = sum(len(t.x) for t in shown if t.mode == "markers")
        ok = df[(df["scene"] == scene) & (df["status"] == "ok")]
        assert markers == len(ok)
        assert sorted(t.name for t in shown if t.mode == "lines") == [
            "Pareto front 64x64", "Pareto front 96x96"]
        hover = next(t for t in shown if t.mode == "markers").text[0]
        assert "time" in hover and " = " in hover  # parameters are in the hover text


def test_crop_of_the_image_grid_is_on_the_reference_edge_band(run_dir, built):
    with np.load(run_dir / "arrays" / "box_plane" / "96x96" / "reference-4spp-seed0.npz") as z:
        ref, covered = z["visibility"], z["covered"]
    r, c, size = report.edge_crop(ref, covered)
    band = report.metrics.edge_band(ref, mask=covered)
    assert band[r:r + size, c:c + size].sum() > 0.1 * size * size


def test_a_techniques_own_maps_are_stored_and_shown(built, run_dir):
    """lispsm stores its texel-size map with its run; the grid shows it in colour."""
    _, page = built
    df = report.current_rows(results.load(run_dir))
    row = df[(df["technique"] == "lispsm") & (df["scene"] == "box_plane")
             & (df["width"] == 96)].iloc[0]
    with np.load(run_dir / row["array"]) as z:
        texel_map = z["map_pixels_per_texel_log2"]
    assert texel_map.shape == (96, 96) and np.isfinite(texel_map).any()
    # the stored map agrees with the run's own column: the largest texel in pixels
    assert 2 ** np.nanmax(texel_map) == pytest.approx(row["alias_max"], rel=1e-5)
    png = Path(row["array"]).stem + "-map-pixels_per_texel_log2.png"
    assert png in page
    assert (run_dir / "images" / "box_plane" / "96x96" / png).is_file()
