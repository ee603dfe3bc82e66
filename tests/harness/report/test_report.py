"""The dashboard: image helpers on hand-made arrays, pages from hand-made results (hostile names,
arrays outside the folder, damaged arrays), then a page built from a real small run."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from harness.technique import registry
from harness import results
from harness.cli import main as shadowbench
from harness.report import build_report, images, scale, stability
from helpers import ROOT, SCALE_SIZES, SCALE_TIMES, hostile_folder, scale_folder



def scene_data(page: str) -> list[dict]:
    """The JSON each scene section carries (runs with their images, plot, references)."""
    return [json.loads(m) for m in re.findall(
        r'<script type="application/json" class="scene-data">(.*?)</script>', page, re.S)]


# --- images on hand-made arrays -----------------------------------------------------------------

def test_edge_crop_lies_on_the_shadow_edge():
    ref = np.ones((128, 128), np.float32)
    ref[:, :40] = 0.0  # a vertical shadow boundary between columns 39 and 40
    r, c, size = images.edge_crop(ref, np.ones_like(ref, bool))
    assert size == 24  # an eighth of 128 is 16, below the 24 px minimum
    assert 0 <= r and r + size <= 128 and c < 40 < c + size
    assert images.edge_crop(np.ones((64, 64)), np.ones((64, 64), bool)) is None


def test_worst_edge_crop_is_where_the_run_errs():
    """A square shadow whose left edge the run gets right and whose right edge (column 96) it
    gets wrong in rows 100..120: the window holds that error. Catches a crop chosen by edge
    pixels alone (it would sit anywhere along the square's outline)."""
    ref = np.ones((128, 128))
    ref[20:120, 30:96] = 0.0
    v = ref.copy()
    v[100:120, 96:99] = 0.0  # shadow spills three columns past the right edge, low down
    compared = np.ones_like(ref, bool)
    r, c, size = images.worst_edge_crop(images.signed_error(v, ref, compared), ref, compared)
    assert r <= 100 and 120 <= r + size + 4 and c <= 96 < c + size


def test_shrunk_error_keeps_a_one_pixel_error():
    """One wrong pixel in 1024x1024 stays one full-strength pixel at 256. Catches averaging the
    error down (it would fade to 1/16)."""
    d = np.zeros((1024, 1024))
    d[517, 301] = -1.0
    d[:4, :4] = np.nan  # a block with nothing compared stays "none"
    shown = images.shrink_error(d)
    assert shown.shape == (256, 256) and shown[129, 75] == -1.0
    assert np.isnan(shown[0, 0]) and np.nansum(np.abs(shown)) == 1.0


def test_scale_maps_values_onto_the_palette_and_nan_onto_none():
    """0 -> the first colour, 1 and anything above -> the last value colour (254), NaN -> 255.
    Catches values above the range taking the "none" colour."""
    index = images.VISIBILITY.index(np.array([0.0, 0.5, 1.0, 2.0, np.nan]))
    assert list(index) == [0, 127, 254, 254, 255]
    assert list(images.ERROR.index(np.array([-1.0, 0.0, 1.0]))) == [0, 127, 254]
    assert tuple(images.ERROR.palette[127]) == (255, 255, 255)  # no error is white
    assert tuple(images.ERROR.palette[254]) == (255, 0, 0)  # lit where the reference is not


def test_stability_marks_failures_nonfinite_and_v_out_of_range():
    rows = pd.DataFrame({
        "scene": ["s"] * 6, "technique": ["a", "a", "b", "c", "d", "e"],
        "status": ["ok", "ok", "error", "ok", "ok", "skipped"],
        "error": ["", "", "boom", "", "", "not applicable"],
        "nonfinite": [0, 0, np.nan, 3, 0, np.nan], "v_min": [0, 0, np.nan, 0, -0.1, np.nan],
        "v_max": [1, 1, np.nan, 1, 1, np.nan], "wrong_pct": [0.5, 2.5, np.nan, 1, 1, np.nan]})
    cells = stability.stability_cells(rows)
    assert not cells[("s", "a")]["fails"] and cells[("s", "a")]["worst_wrong_pct"] == 2.5
    assert cells[("s", "b")]["fails"] and cells[("s", "b")]["first_error"] == "boom"
    assert cells[("s", "c")]["fails"] and cells[("s", "c")]["nonfinite"] == 1
    assert cells[("s", "d")]["fails"] and cells[("s", "d")]["out_of_range"] == 1
    assert not cells[("s", "e")]["fails"] and cells[("s", "e")]["skipped"] == 1


# --- pages from hand-made results ---------------------------------------------------------------


def test_hostile_names_reach_the_page_only_as_text(tmp_path, make_results):
    """Catches any unescaped output: a template without autoescape, a ``|safe`` on data, JSON
    in a script element that can close it, a name used raw as a file or an id."""
    folder = hostile_folder(tmp_path / "run", make_results)
    page = build_report(folder).read_text()
    assert "onerror=\"document" not in page and "<img src=x" not in page
    assert "</script><script>alert" not in page
    assert len(re.findall(r"<script[ >]", page)) == 2 + 1  # charts.js, page.js, the scene's data
    assert "x&#34; onerror=&#34;document.title=&#39;PWNED&#39;&#34;" in page  # shown, as text
    written = [p for p in folder.rglob("*") if p.is_file()]
    assert all(p.resolve().is_relative_to(folder.resolve()) for p in written)
    assert not any("onerror" in p.name or '"' in p.name for p in written)


def test_arrays_are_read_only_from_inside_the_folder(tmp_path, make_results):
    """A row whose ``array`` leads outside the folder (to a real run's arrays) shows no images
    and a note; the other runs show theirs. Catches following results.csv's paths anywhere."""
    elsewhere = make_results(tmp_path / "elsewhere", [{}])
    folder = make_results(tmp_path / "run", [{"params": {"res": 512}}, {"params": {"res": 1024}}])
    rows = results.read_rows(folder)
    rows[1]["array"] = "../elsewhere/arrays/run-0.npz"
    results.write_rows(folder, rows)
    assert (folder / rows[1]["array"]).is_file()
    page = build_report(folder).read_text()
    runs = {r["setting"]: r for r in scene_data(page)[0]["runs"]}
    assert runs["res=512"]["images"]["v"].startswith("data:image/")
    assert runs["res=1024"]["images"] is None
    assert "&#39;../elsewhere/arrays/run-0.npz&#39; points outside" in page
    del elsewhere


def test_a_damaged_or_missing_array_shows_that_run_unavailable(tmp_path, make_results):
    """A truncated .npz and a deleted one: those runs show why they have no images, the page
    names them in its notes, the third run is shown. Catches a BadZipFile or FileNotFoundError
    ending the report."""
    folder = make_results(tmp_path / "run", [{"params": {"res": r}} for r in (512, 1024, 2048)])
    damaged = folder / "arrays" / "run-1.npz"
    damaged.write_bytes(damaged.read_bytes()[:40])
    (folder / "arrays" / "run-2.npz").unlink()
    page = build_report(folder).read_text()
    runs = {r["setting"]: r for r in scene_data(page)[0]["runs"]}
    assert runs["res=512"]["images"] is not None
    assert runs["res=1024"]["images"] is None and runs["res=2048"]["images"] is None
    assert "missing, damaged" in runs["res=1024"]["unavailable"]
    assert "arrays/run-1.npz cannot be read (BadZipFile)" in page
    assert "arrays/run-2.npz cannot be read (FileNotFoundError)" in page


def test_scenes_built_by_worker_processes_make_the_page_one_process_makes(
        tmp_path, make_results, monkeypatch):
    """Three scenes of 1, 3 and 2 runs (handed to the workers largest first), one with a damaged
    array: two worker processes give the page one process gives, the sections in the results'
    order and the worker's note on the damaged array on it. Catches sections in the order the
    workers finish and a worker's notes lost with its process."""
    from harness import report

    runs = [{"scene": scene, "params": {"res": 256 * (i + 1)}}
            for scene, count in (("c", 1), ("a", 3), ("b", 2)) for i in range(count)]
    folder = make_results(tmp_path / "run", runs)
    damaged = folder / "arrays" / "run-2.npz"
    damaged.write_bytes(damaged.read_bytes()[:40])
    pages = {}
    for workers in (1, 2):
        monkeypatch.setattr(report, "_cpus", lambda: workers)
        pages[workers] = re.sub(r"page built \S+", "", build_report(folder).read_text())
    assert pages[2] == pages[1]
    assert re.findall(r'<section class="view scene" id="scene-(\w+)"', pages[2]) == ["c", "a", "b"]
    assert "arrays/run-2.npz cannot be read (BadZipFile)" in pages[2]


def test_report_on_a_folder_without_results_is_one_line(tmp_path, capsys):
    """Catches a traceback (FileNotFoundError, KeyError on a foreign CSV) instead of exit 2."""
    (tmp_path / "foreign").mkdir()
    (tmp_path / "foreign" / "results.csv").write_text("a,b\n1,2\n")
    for folder, why in ((tmp_path, "no results.csv"),
                        (tmp_path / "foreign", "not a shadowbench results file")):
        assert shadowbench(["report", str(folder)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and why in err[0]


# --- a page built from a real run ---------------------------------------------------------------

@pytest.fixture(scope="module")
def run_dir(tmp_path_factory, small_run_dir):
    return small_run_dir(tmp_path_factory.mktemp("dashboard") / "run")


@pytest.fixture(scope="module")
def built(run_dir):
    index = build_report(run_dir)
    return index, index.read_text()


def test_page_is_one_file_that_loads_nothing_from_elsewhere(built):
    """Catches images referenced as files (broken when index.html is copied alone) and any
    library fetched from a network."""
    _, page = built
    assert not re.search(r"""(src|href)=["'](?!data:|#)""", page.replace(
        'href="#', "").replace("href='#", ""))
    assert "<script src" not in page and "plotly" not in page.lower()
    for data in scene_data(page):
        for run in data["runs"]:
            if run["images"]:
                assert run["images"]["v"].startswith("data:image/")
    assert len(page) < 3_000_000


def test_every_ok_run_has_its_images_and_shaded_scenes_their_shaded_images(built, run_dir):
    """Not only the defaults: every ok run (the sm and pcf grids too) has V, error and an edge
    crop; sphere_plane (effects: direct) has shaded images, box_plane none. Catches a viewer
    limited to default runs and a shaded image that is never shown."""
    _, page = built
    df = results.load(run_dir)
    for data in scene_data(page):
        ok = [r for r in data["runs"] if r["status"] == "ok"]
        assert ok and all(r["images"] and r["images"]["err"] and r["images"]["crop"] for r in ok)
        scene = "sphere_plane" if any(r["images"]["shaded"] for r in ok) else "box_plane"
        shaded = scene == "sphere_plane"
        assert all(bool(r["images"]["shaded"]) == shaded for r in ok)
        assert all(bool(ref["shaded"]) == shaded for ref in data["references"].values())
        assert len(ok) == ((df["scene"] == scene) & (df["status"] == "ok")).sum()


def test_curves_join_each_techniques_runs_in_knob_order(built):
    """sm's res grid and pcf's k grid at 96x96 are lines in knob order labelled with their
    setting. Catches points left unjoined or joined in the order they were run."""
    _, page = built
    data = next(d for d in scene_data(page) if d["plot"]["sizes"] == ["64x64", "96x96"]
                and "flip" not in d["plot"]["errors"])
    view = data["plot"]["views"]["time_ms|edge_mae"]
    labels = {(line["technique"], line["size"]): line["labels"] for line in view["lines"]
              if len(line["runs"]) > 1}
    assert labels[("sm", "96x96")] == ["res=256", "res=1024"]
    assert labels[("pcf", "96x96")] == ["k=4", "k=16"]
    assert view["front"] and all(isinstance(i, int) for i in view["front"])


def test_descriptions_reach_the_list_and_the_page(built, capsys):
    """Catches a description dropped on the way (config, manifest, page, ``shadowbench list``)."""
    from harness import config

    described = config.load_scenes(ROOT / "scenes.yaml")["box_plane"].description
    assert described and described in built[1].replace("&#39;", "'")
    assert shadowbench(["list", "--scene-file", str(ROOT / "scenes.yaml")]) == 0
    assert described in capsys.readouterr().out


def test_a_techniques_own_maps_are_shown(built, run_dir):
    """lispsm stores its texel-size map with its run; the viewer shows it with its range."""
    _, page = built
    df = results.load(run_dir)
    row = df[(df["technique"] == "lispsm") & (df["scene"] == "box_plane")
             & (df["width"] == 96)].iloc[0]
    with np.load(run_dir / row["array"]) as z:
        texel_map = z["map_pixels_per_texel_log2"]
    runs = [r for d in scene_data(page) for r in d["runs"]
            if r["technique"] == "lispsm" and r["size"] == "96x96" and r["images"]]
    maps = [m for r in runs for m in r["images"]["maps"]]
    assert maps and maps[0]["name"] == "pixels_per_texel_log2"
    finite = texel_map[np.isfinite(texel_map)]
    assert min(m["lo"] for m in maps) >= finite.min() - 1e-6


# --- what the page is built from ----------------------------------------------------------------

def test_theta_plot_appears_with_three_angles():
    """alias_mean and edge_mae against theta per technique, joined in angle order (scenes that
    differ in their light alone), only when the runs span three angles or more. Catches a plot
    drawn from two angles or joined unsorted."""
    from harness.report import plots

    rows = pd.DataFrame({
        "scene": ["a", "b", "c", "a"], "technique": ["psm"] * 3 + ["sm"], "width": [64] * 4,
        "height": [64] * 4, "params": [{"res": 512}] * 4, "theta_deg": [60.0, 20.0, 40.0, 60.0],
        "alias_mean": [1.5, 3.0, 2.0, np.nan], "edge_mae": [0.1, 0.3, 0.2, 0.05],
        "triangles": [500] * 4, "parts": [2] * 4, "covered_px": [2000] * 4})
    spec = plots.theta(rows, {"psm": "#111", "sm": "#222"})
    alias = next(f for f in spec["facets"] if f["title"] == "alias_mean")
    assert [(p["x"], p["y"]) for p in alias["series"][0]["points"]] == [
        (20.0, 3.0), (40.0, 2.0), (60.0, 1.5)]
    assert plots.theta(rows[rows["scene"] != "c"], {"psm": "#111", "sm": "#222"}) is None


def test_noisy_runs_are_counted_and_warned_of_beyond_five_percent():
    """Catches a warning that never fires (or always does) and noisy counted among untimed."""
    from harness.report import overview

    def counts(noisy):
        rows = pd.DataFrame({"status": ["ok"] * len(noisy), "noisy": noisy})
        return overview.counts(rows, rows)

    assert counts([1, 0] + [0] * 18) == {**counts([1, 0] + [0] * 18), "noisy": 1, "timed": 20,
                                         "noisy_warning": False}
    assert counts([1, 1] + [0] * 18)["noisy_warning"]
    assert counts([np.nan] * 5)["timed"] == 0


def test_rewording_a_description_keeps_the_scene_key(shipped_scenes):
    """The description is prose: references and run ids must not change with it. Catches a
    scene key that hashes every field."""
    from harness.scene import scene_key

    scene = shipped_scenes["box_plane"]
    reworded = scene.model_copy(update={"description": "something else"})
    moved = scene.model_copy(update={"ambient": 0.3})
    assert scene_key(reworded) == scene_key(scene) != scene_key(moved)


def test_evaluate_takes_a_scene_name_and_a_scene_file(gl_context):
    """``evaluate("box_plane", ...)`` failed with AttributeError on a str."""
    from harness.run import evaluate

    result = evaluate("box_plane", "sm", scene_file=ROOT / "scenes.yaml", resolution=(48, 32),
                      samples=4)
    assert result.row["status"] == "ok" and result.visibility.shape == (32, 48)


# --- the Scale view and the verdict per size band ------------------------------------------------


def test_scale_view_shows_the_exponents_and_the_crossing(tmp_path, make_results):
    """The page of scale_folder: sm's time exponent log10(2) = 0.301 (its times double per
    decade); sv's, by hand, the slope of log10 (0.25, 1, 8, 32) on 3..6: 3.6124 / 5 = 0.722;
    sv's volume pass's fragments exponent 1; sv costs more than sm above 10^4.5 = 31,623
    triangles, between 10,000 (0.5x) and 100,000 (2x); both time charts hold each technique's
    four sizes. Catches: a view not built, the exponent of the whole frame confused with a
    pass's, a crossing lost on the way to the page, a defaults chart that misses sv's defaults."""
    page = build_report(scale_folder(tmp_path / "run", make_results)).read_text()
    assert '<section class="view" id="scale">' in page and 'href="#scale"' in page
    view = page[page.index('id="scale"'):page.index('id="scene-')]
    exponents = view[view.index('class="exponents"'):]
    sm_row = exponents[exponents.index("<b>sm</b>"):]
    assert re.match(r"<b>sm</b></td><td></td>\s*<td>0\.301", sm_row)
    sv_row = exponents[exponents.index("<b>sv</b>"):]
    assert re.match(r"<b>sv</b></td><td></td>\s*<td>0\.722 <small>\[", sv_row)
    assert re.search(r"<td>volumes</td><td>0\.722 <small>\[[^]]+\]</small></td>"
                     r"<td>1 <small>\[1, 1\]</small></td><td>—</td>", sv_row)
    crossing = re.search(r"<b>sv</b></td><td>.*?sm</td>\s*<td><b>([\d,]+) triangles</b><br>"
                         r"<small>between ([\d,]+) \(([\d.]+)×\) and ([\d,]+) \(([\d.]+)×\)",
                         view)
    assert crossing.groups() == ("31,623", "10,000", "0.5", "100,000", "2")
    assert "1,000: 0.25× · 10,000: 0.5× · 100,000: 2× · 1,000,000: 4×" in view
    specs = dict(re.findall(r'<script type="application/json" class="chart-spec" '
                            r'data-for="([^"]+)">(.*?)</script>', view, re.S))
    for chart in ("scale-cost", "scale-defaults"):  # every run is both at defaults and within
        lines = {s["name"]: [(p["x"], p["y"]) for p in s["points"]]
                 for s in json.loads(specs[chart])["facets"][0]["series"]}
        assert lines == {t: list(zip(SCALE_SIZES, times)) for t, times in SCALE_TIMES.items()}
    fronts = json.loads(specs["scale-front-0"])
    assert [f["title"] for f in fronts["facets"]] == [
        "1,000 triangles", "10,000 triangles", "100,000 triangles", "1,000,000 triangles"]


def test_crossovers_weigh_a_technique_against_the_rivals_its_class_names(tmp_path, make_results):
    """rt declares sv and silhouette its rivals (issue 36: rays against volumes), so scale_folder
    with rt added at half sm's times (0.5, 1, 2, 4 ms) gets an rt-against-sv row besides rt
    against sm: ratios 0.5 / 0.25 = 2, 1 / 1 = 1, 2 / 8 = 0.25, 4 / 32 = 0.125 at 10^3..10^6,
    no crossing (rt costs at most sv's at the largest size). silhouette has no runs: no row.
    Each unordered pair once (sv against sm only as sv's row). Catches the table built against
    the baseline alone (the seed's), and a pair listed twice when two techniques name each
    other."""
    folder = scale_folder(tmp_path / "run", make_results)
    rows = results.read_rows(folder)
    rt_version = registry.get("rt").code_version()
    rows += [{**row, "technique": "rt", "code_version": rt_version, "time_ms": float(row["time_ms"]) / 2,
              "run_id": f"{row['run_id']}-rt"}
             for row in rows if row["technique"] == "sm" and row["scene"].startswith("arch@")]
    results.write_rows(folder, rows)
    view = build_report(folder).read_text()
    view = view[view.index('class="crossovers"'):view.index('class="exponents"')]
    pairs = re.findall(r"<b>(\w+)</b></td><td>.*?</span>(\w+)</td>", view)
    assert sorted(pairs) == [("rt", "sm"), ("rt", "sv"), ("sv", "sm")]
    assert "1,000: 2× · 10,000: 1× · 100,000: 0.25× · 1,000,000: 0.125×" in view
    assert "rt costs at most sv&#39;s at the largest size" in view
    assert scale.compared_pairs({"rt", "ptsv", "sv"}, None,
                                {"rt": ("ptsv",), "ptsv": ("rt", "sv")}) == [
        ("ptsv", "rt"), ("ptsv", "sv")]


def test_the_overview_judges_each_size_band_apart(tmp_path, make_results):
    """scale_folder's scenes fall in four bands: box and arch@1e3 below 10^4, arch@1e4 and
    arch@1e5 in 10^4 to 10^5, arch@1e6 above, old (no count) in the unknown band with its
    note. sv's median ratio to sm at equal error is 0.25 below, (0.5 + 2) / 2 = 1.25 in the
    middle band and 4 above. Without family rows there is no Scale view. Catches: scenes pooled
    into one verdict (1.25 in every band), a scene without a count put in the lowest band, a
    Scale view on ordinary results."""
    page = build_report(scale_folder(tmp_path / "run", make_results)).read_text()
    bands = re.findall(r'<h3 class="band">(.*?) <small>\d+ scenes?: (.*?)</small></h3>', page)
    assert bands == [("below 10⁴ triangles", "arch@1000, box"),
                     ("10⁴ to 10⁵ triangles", "arch@10000, arch@100000"),
                     ("above 10⁵ triangles", "arch@1e+06"), ("unknown size", "old")]
    assert "run before it was recorded" in page
    for band, ratio in (("below 10⁴", "0.25× <small>over 1 levels"),
                        ("10⁴ to 10⁵", "1.25× <small>over 2 levels"),
                        ("above 10⁵", "4× <small>over 1 levels")):
        table = page[page.index(f'data-band="{band} triangles"'):]
        start = table.index("<b>sv</b>")
        assert ratio in table[start:table.index("</tr>", start)], band
    plain = build_report(make_results(tmp_path / "plain", [{}])).read_text()
    assert 'id="scale"' not in plain and "unknown size" in plain
