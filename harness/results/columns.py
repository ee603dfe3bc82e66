"""The results record's columns, each with its type, unit, meaning and when it is empty: one
table from which :mod:`harness.results` takes its schema and ``docs/results.md`` is generated
(``python -m harness.results.columns > docs/results.md``; a test keeps the page equal to it), so the
schema and its documentation cannot drift. A column without its line here is not written."""

from __future__ import annotations

import sys
from typing import NamedTuple


class Column(NamedTuple):
    name: str
    type: type
    unit: str
    meaning: str
    empty: str = "never"  # when the cell is empty


_PER_FRAME = "per frame: the median over the measured frames"
_ERROR = "where the run failed or was skipped"
_COMPARED = ("over the compared pixels (covered in both views, facing the light, inside a spot "
             "light's cone)")
_COUNTERS = ("where the GL driver has no pipeline statistics (the manifest's "
             "gl.pipeline_statistics says why), or the run failed")
_MOVING = "on a still scene"

COLUMN_TABLE: tuple[Column, ...] = (
    Column("run_id", str, "", "the run's stable id: a hash of scene, size, technique, parameters, "
           "code version, frames, warm-up, statistics, reference settings, metrics version, "
           "cost policy; a rerun with the same id is skipped"),
    Column("schema", int, "", "the version of this record's layout (harness.results."
           "SCHEMA_VERSION)"),
    Column("scene", str, "", "the scene's name in the scene file; `name@1e5` for a family scene "
           "at an experiment's triangle count"),
    Column("technique", str, "", "the technique's registry key (entry point name)"),
    Column("params", str, "JSON", "every parameter of the run (defaults included), canonical "
           "JSON; `results.load` parses it into a dict"),
    Column("family", str, "", "the scene's procedural family", "for a scene of objects"),
    Column("width", int, "px", "camera image width"),
    Column("height", int, "px", "camera image height"),
    Column("map_res", float, "texels", "the shadow map's width and height (the technique's `res` "
           "parameter); `res` in folders written before it was renamed, which `results.load` "
           "reads as `map_res`", "for a technique without a `res` parameter (sv)"),
    Column("triangles", int, "count", "triangles in the scene as rendered (all copies)", _ERROR),
    Column("parts", int, "count", "separate meshes (object copies, mesh parts, family pieces)",
           _ERROR),
    Column("open_parts", int, "count", "parts not closed (an edge not shared by exactly two "
           "faces)", _ERROR),
    Column("shadow_edges", int, "count", "silhouette edges as seen from the light", _ERROR),
    Column("time_ms", float, "ms", f"the technique's own passes, {_PER_FRAME} (on llvmpipe a CPU "
           "cost; rank, do not read as GPU time)", _ERROR),
    Column("time_ms_min", float, "ms", "the fastest measured frame", _ERROR),
    Column("time_ms_max", float, "ms", "the slowest measured frame", _ERROR),
    Column("frames", int, "count", "measured frames (after the warm-up); a moving scene's "
           "sequence length"),
    Column("time_ms_ci_low", float, "ms", "lower end of the 95% interval of time_ms (the "
           "experiment's `statistics`)", _ERROR),
    Column("time_ms_ci_high", float, "ms", "upper end of that interval", _ERROR),
    Column("frame_ms", str, "JSON list of ms", "each measured frame's total; `results.load` "
           "parses it into a list", _ERROR),
    Column("cost", str, "", "the cost policy: `dynamic` (every frame redoes what depends on "
           "light and geometry) or `static` (that is setup_ms)"),
    Column("prepare_ms", float, "ms", "the wall time of the technique's `prepare` (GL work "
           "included), once per run: one-off preprocessing (edge meshes, bottom-level BVHs), "
           "uploads, shaders; charged in no frame under either policy", _ERROR),
    Column("setup_ms", float, "ms", "under `static`: the update's median time, done once",
           "under `dynamic`, or the run failed"),
    Column("setup_ms_ci_low", float, "ms", "lower end of setup_ms's 95% interval",
           "as setup_ms"),
    Column("setup_ms_ci_high", float, "ms", "upper end of setup_ms's 95% interval",
           "as setup_ms"),
    Column("cpu_contention", float, "fraction", "share of the CPU other processes used while "
           "the run was timed", "where the load cannot be read, or the run failed"),
    Column("noisy", int, "0/1", "1 when cpu_contention was above the noisy threshold (the "
           "manifest's timing.noisy_contention): the times are inflated", "as cpu_contention"),
    Column("scene_ms", float, "ms", "the shared G-buffer pass (camera view), not counted in "
           "time_ms", _ERROR),
    Column("frags_scene", float, "count", "fragments of the camera view (occlusion query)",
           _ERROR),
    Column("frags_shadow", float, "count", "fragments of the technique's own passes, or the "
           "shadow-volume fill a technique counts itself", _ERROR),
    Column("overdraw", float, "ratio", "frags_shadow / frags_scene (O in the silhouette-map "
           "paper)", _ERROR),
    Column("mem_bytes", float, "bytes", "the technique's maps and buffers", _ERROR),
    Column("fetches_per_px", float, "count", "texture fetches per shaded pixel", _ERROR),
    Column("alpha", str, "", "what the run did with the scene's alpha-tested casters: `none` "
           "(it has none), `tested` (the technique cuts them out by the texture's alpha), "
           "`ignored` (its `alpha: ignore` drew them opaque: its error shows what that costs), "
           "`declined` (skipped, the reason in `error`)", "where the run stopped before it "
           "was prepared (a light type declined), and in folders written before the column"),
    Column("covered_px", float, "px", "camera pixels covered by geometry", _ERROR),
    Column("vertex_invocations", float, "count", f"vertices shaded in the measured passes, "
           f"{_PER_FRAME}", _COUNTERS),
    Column("fragment_invocations", float, "count", "fragment shader invocations (llvmpipe counts "
           "4x4 blocks)", _COUNTERS),
    Column("primitives", float, "count", "primitives reaching the rasteriser", _COUNTERS),
    Column("compute_invocations", float, "count", "compute shader invocations (the GPU "
           "reductions)", _COUNTERS),
    Column("traversal_nodes", float, "count", "nodes of a hierarchy a technique's traversal "
           "tested in one frame (counted in an untimed repeat): BVH nodes its rays entered, "
           "nodes of view samples its shadow volumes were tested against, or view samples "
           "linked into an irregular z-buffer's lists",
           "for a technique that traverses no hierarchy"),
    Column("triangle_tests", float, "count", "that traversal's tests of one triangle at the "
           "leaves in one frame: against a ray, or (its shadow volume or frustum) against a "
           "view sample", "as traversal_nodes"),
    Column("gpu_estimate_ms", float, "ms", "the counted work priced at an RTX 4090's peak rates "
           "(harness.analysis.cost_model: a lower bound)", _COUNTERS),
    Column("mae", float, "V (0..1)", f"mean |V - V_ref| {_COMPARED}", _ERROR),
    Column("rmse", float, "V (0..1)", "root mean square of V - V_ref, same pixels", _ERROR),
    Column("wrong_pct", float, "%", "compared pixels where |V - V_ref| > 0.5", _ERROR),
    Column("edge_mae", float, "V (0..1)", "mean |V - V_ref| within 2 px of a reference shadow "
           "boundary (the edge band)", _ERROR),
    Column("ssim", float, "0..1", "mean structural similarity of V and V_ref", _ERROR),
    Column("psnr", float, "dB", "peak signal-to-noise ratio of V against V_ref; inf when equal",
           _ERROR),
    Column("flip", float, "0..1", "mean FLIP of the shaded image against the shaded reference",
           "where the scene asks for no shading (effects without `direct`)"),
    Column("levels", float, "count", "distinct V values inside the edge band (2 for a 0/1 "
           "technique)", _ERROR),
    Column("acne_pct", float, "%", "compared pixels, outside the edge band, that the reference "
           "sees fully lit and V < 0.98 (false self-shadow)", _ERROR),
    Column("leak_pct", float, "%", "compared pixels, outside the edge band, that the reference "
           "sees fully shadowed and V > 0.02 (light leaks)", _ERROR),
    Column("edge_floor", float, "V (0..1)", "edge_mae of the reference rounded to 0/1: the best "
           "a technique answering 0 or 1 can reach", _ERROR),
    Column("edge_ratio", float, "ratio", "edge_mae / edge_floor", "where edge_floor is 0, or "
           "the run failed"),
    Column("world_flicker", float, "V (0..1)", "mean change of V between frames at fixed world "
           "points (shimmer)", _MOVING),
    Column("world_flicker_max", float, "V (0..1)", "the largest frame's world_flicker",
           _MOVING),
    Column("world_changed_pct", float, "%", "pixels whose V changed at a fixed world point, mean "
           "over frames", _MOVING),
    Column("world_changed_pct_max", float, "%", "the largest frame's world_changed_pct",
           _MOVING),
    Column("nonfinite", float, "count", "NaN and Inf values seen in the technique's matrices "
           "and in V", _ERROR),
    Column("v_min", float, "V (0..1)", "smallest V of the last frame", _ERROR),
    Column("v_max", float, "V (0..1)", "largest V of the last frame", _ERROR),
    Column("passes", str, "JSON list", "each measured pass: name, ms (median) with its interval, "
           "fragments, counters; `results.load` parses it into a list of dicts", _ERROR),
    Column("renderer", str, "", "the GL_RENDERER string", "where the scene could not be "
           "prepared"),
    Column("status", str, "", "`ok`, `skipped` (the technique does not apply: error says why) "
           "or `error`"),
    Column("error", str, "", "why the run failed or was skipped, one line", "when status is ok"),
    Column("warnings", str, "", "warnings raised while the run was scored, `; `-separated",
           "when there were none"),
    Column("mesh_notes", str, "", "what the scene's mesh files hold that defines no triangle, "
           "skipped and counted, one line per file (`m.obj: skipped 201 faces with fewer than "
           "3 vertices`)", "when nothing was skipped"),
    Column("code_version", str, "", "hash of the technique's code (module, imported siblings, "
           "shaders): rows of an older version are stale (see below)"),
    Column("texels_per_pixel_median", float, "ratio", "a map technique's texel side over the "
           "pixel's, both on the receiver's plane (1 / sqrt of the area a pixel covers in "
           "the map's texels, as the technique reports it): the median over the pixels the "
           "light reaches; below 1 the map is finer than the view, above 1 coarser (aliasing)",
           "for a technique without a depth map (sv, ptsv, rt), or the run failed"),
    Column("texels_per_pixel_p95", float, "ratio", "the 95th percentile of that ratio",
           "as texels_per_pixel_median"),
    Column("ref_samples", int, "count", "reference samples per pixel"),
    Column("ref_seconds", float, "s", "time the reference took to trace when it was computed "
           "(a cached reference keeps that figure)", "where the scene could not be prepared"),
    Column("ref_build_seconds", float, "s", "of ref_seconds, building the reference's Mitsuba "
           "scene", "where the scene could not be prepared, or the cache entry predates it"),
    Column("array", str, "path", "the run's arrays (V, coverage, maps), relative to the results "
           "folder", _ERROR),
    Column("reference_array", str, "path", "the reference's arrays, relative to the folder",
           _ERROR),
    Column("finished_at", str, "UTC ISO 8601", "when the row was written"),
    # shadowbench tune (docs/fairness.md)
    Column("tuning", str, "", "the run's part in `shadowbench tune`: `defaults` (the technique "
           "at its defaults at a point of its quality curve, timed), `baseline` (the baseline "
           "technique at its defaults on the searched view: the leak limit), `search` (a setting "
           "the search tried, one frame), `best` (the setting chosen, timed), `held_out` (the "
           "best on a second view), `window` (a scale of the best's bias terms)",
           "for a run not made by tune"),
    Column("tuned_on", str, "", "the view the settings were tuned on: the scene's name, or "
           "`<scene>.frame0` for the first frame of a moving scene", "as tuning"),
    Column("tune_point", str, "", "the point of the quality curve the run belongs to: each "
           "quality knob as `name=value` (`k=16 res=1024`)", "as tuning"),
    Column("leak_limit", float, "%", "the search's leak limit: the baseline's leak_pct at "
           "defaults and the same map size on the searched view, plus 0.1", "as tuning"),
    Column("tuning_met", int, "0/1", "on a best row: 1 when the setting meets acne_pct <= 0.1 "
           "and leak_pct <= leak_limit on the searched view, 0 when none tried does (the "
           "closest kept)", "except on best rows"),
    Column("tuning_trials", int, "count", "on a best row: the settings the search tried",
           "except on best rows"),
    Column("held_out_edge_mae", float, "V (0..1)", "on a best row of a still scene: edge_mae "
           "of the best setting on the view orbited 10 degrees about the camera's target (over-"
           "tuning shows as a rise over edge_mae)", "except on best rows of still scenes"),
    Column("bias_scale", float, "ratio", "on a window row: the factor every bias term of the "
           "best setting was multiplied by", "except on window rows"),
    Column("bias_window", float, "log10 ratio", "on the best row of a technique's window "
           "point: log10 of the width of the bias scales with acne_pct <= 0.1 and leak_pct <= "
           "leak_limit (harness.analysis.tuning.bias_window); 0 where none qualifies",
           "except on that row"),
)

# name -> type; these keep their names and meaning (DESIGN.md). Techniques may add columns.
COLUMNS: dict[str, type] = {c.name: c.type for c in COLUMN_TABLE}
# columns written as JSON, which results.load parses
JSON_COLUMNS = tuple(c.name for c in COLUMN_TABLE if c.unit.startswith("JSON"))
# old column names, read as their new ones
RENAMED = {"res": "map_res"}

PAGE_HEAD = """\
# results.csv: the columns

<!-- Generated by `python -m harness.results.columns > docs/results.md` from harness/results/columns.py, the
record schema itself; edit that file, not this page (tests/harness/test_results_columns.py
fails when the two differ). -->

One row per run (scene x size x technique x parameters). `harness.results.load(DIR)` reads it
as a pandas DataFrame: numbers typed, `params`, `frame_ms` and `passes` parsed from JSON, and
**stale rows dropped** (see below).

| column | unit | meaning | empty |
|---|---|---|---|
"""

PAGE_TAIL = """
## Columns not in the table

- A technique may add columns of its own (`ShadowOutput.extra`: csm's cascades, mdsm's
  `select_fetches`, silhouette's `sil_pct`, sv's fill counts, the warps' aliasing figures);
  its class docstring says what they are. They follow these columns, sorted by name.
- On a moving scene each error metric is the mean over the sequence's frames, and
  `<metric>_min` and `<metric>_max` give the range (`mae_max`, ...).

## Stale rows

A row is **stale** when a later row of the same scene, size, technique and parameters has
another `code_version`: the technique's code changed and the run was made again. The file keeps
both (nothing is lost), and `results.load(DIR)` drops the stale ones by default;
`results.load(DIR, stale="flag")` keeps them with a boolean `stale` column. The dashboard goes
further (`harness.analysis.current`): it keeps only rows of the code installed now.
"""


def page() -> str:
    """docs/results.md."""
    def cell(text: str) -> str:
        return text.replace("|", "\\|") or "-"

    rows = "".join(f"| `{c.name}` | {cell(c.unit)} | {cell(c.meaning)} | {cell(c.empty)} |\n"
                   for c in COLUMN_TABLE)
    return PAGE_HEAD + rows + PAGE_TAIL


if __name__ == "__main__":
    sys.stdout.write(page())
