"""``shadowbench tune``: each technique's tunable settings searched against the reference on the
user's scene, point by point of its quality curve, and the settings chosen scored beside the
defaults (docs/fairness.md).

Per scene, in the order its data flows:

1. the view searched: the scene, or the first frame of a moving scene (``<scene>.frame0``);
   one G-buffer and one reference for the whole search;
2. the baseline technique at its defaults at each map size tuned, on that view: its leak_pct
   plus LEAK_MARGIN is the search's leak limit there (``tuning: baseline``);
3. the searches (:mod:`harness.run.tune_search`), in rounds: each round asks every point's
   study for one setting and renders them together as one group (``tuning: search``, one
   frame each: error, not time, is searched), until each has spent its budget;
4. on a still scene, each best setting and the defaults on the view orbited HELD_OUT_DEGREES
   about the camera's target (``held_out``), their edge_mae the ``held_out_edge_mae`` of the
   best and the defaults rows;
5. per technique, the best setting of its window point with every bias term scaled by each of
   WINDOW_SCALES (``window``): its ``bias_window``;
6. each point at its defaults and at its best setting, timed with the run's frames, on the
   scene itself (a moving scene: every frame; ``defaults``, ``best``).

Every run is a row of DIR/results.csv with a run id, so a rerun renders only what is missing:
the searches are seeded and ask again the settings already stored, whose rows are read back.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .. import config as cfg
from .. import results
from ..analysis.tuning import ACNE_LIMIT, LEAK_MARGIN, bias_window
from ..config.cache_entry import take_rebuilt_notes
from ..technique import registry
from ..technique.tunable import scaled_bias
from .manifest import MANIFEST_FILE, SPACE_RESERVE, SPACE_RESERVE_BYTES, read_manifest, write_manifest
from .plan import Plan, RunSpec, validate_params
from .store import exclusive, utc_now
from .tune_render import ViewRenderer
from .tune_search import Search, metric, study_seed

SEARCH_FRAMES = 1  # each setting searched is scored on one frame, after no warm-up
HELD_OUT_DEGREES = 10.0
# the bias window's scales: 10^-2 .. 10^2 of the best setting's bias terms, half a decade apart
WINDOW_SCALES = tuple(10.0 ** (e / 2) for e in range(-4, 5))
# the parameter the record stores as map_res (harness.run.score): the map size a point is at
MAP_SIZE = "res"


@dataclass
class Point:
    """One scene, technique and point of its quality curve: the point at its own settings
    (``spec``, timed, on the scene), its label and its search."""

    spec: RunSpec
    label: str
    search: Search
    leak_limit: float = math.nan
    best: object = None  # tune_search.Tried
    met: bool = False
    held_out: dict = dataclasses.field(default_factory=dict)  # edge_mae held out: best, defaults
    window: float = math.nan
    timed: dict | None = None  # the timed rows: {"defaults": row, "best": row}


def tune_grids(cls) -> cfg.Grid:
    """Without an experiment, what tune walks of a technique: its quality curve along the map
    size where it declares that knob (the bias a map needs follows its texel size), else its
    whole curve (csm's splits), else its defaults."""
    knobs = cls.quality_knobs
    if MAP_SIZE in knobs:
        return cfg.Grid(curve={MAP_SIZE: list(knobs[MAP_SIZE])})
    return cfg.Grid(curve=True) if knobs else cfg.Grid()


def point_label(cls, params: dict) -> str:
    """The point's quality knobs as ``name=value`` (``k=16 res=1024``); ``defaults`` without."""
    return " ".join(f"{k}={params[k]}" for k in sorted(cls.quality_knobs) if k in params) \
        or "defaults"


def untunable(plan: Plan) -> list[str]:
    """The plan's techniques that declare nothing tunable."""
    names = dict.fromkeys(spec.technique for spec in plan.runs)
    return [name for name in names if not registry.get(name).tunable]


def tune(plan: Plan, out_dir: str | Path, *, budget: int, seed: int, fixed: dict[str, set],
         progress: bool = True) -> tuple[int, dict]:
    """Tune every point of the plan (its runs are the points, at their settings); returns the
    exit code (0, or 1 when runs failed) and what was chosen per scene, technique and point
    (:func:`harness.run.tune_output.summary_lines` and ``tuned.yaml`` read it).

    ``fixed``: per technique the parameters the command line set, left out of the search."""
    from ..gl.context import get_context
    from ..machine.interrupt import raise_if_interrupted

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    say = (lambda line: print(line, file=sys.stderr, flush=True)) if progress else (lambda _: None)
    chosen: dict = {}
    with exclusive(out_dir):
        read_manifest(out_dir)
        results.remove_temporaries(out_dir, (results.RESULTS_FILE, MANIFEST_FILE, SPACE_RESERVE))
        results.mark_damaged_runs(out_dir)
        context = get_context()
        session = {"id": os.urandom(4).hex(), "command": "tune", "started": utc_now(),
                   "finished": None, "status": "running", "budget": budget, "seed": seed,
                   "runs_rendered": 0, "notes": take_rebuilt_notes()}
        results.replace_atomically(out_dir / SPACE_RESERVE,
                                   lambda f: f.write(bytes(SPACE_RESERVE_BYTES)))
        write_manifest(out_dir, plan, context, session)
        renderer = ViewRenderer(out_dir, context.renderer)
        try:
            for (scene_name, width, height), specs in _by_scene(plan).items():
                raise_if_interrupted()
                scene = plan.scenes[scene_name].with_resolution(width, height)
                chosen[(scene_name, width, height)] = _tune_scene(
                    scene, specs, renderer, budget=budget, seed=seed, fixed=fixed, say=say)
                renderer.release_all()
            session["status"] = "complete"
        except KeyboardInterrupt:
            session["status"] = "interrupted"
            raise
        except BaseException:
            session["status"] = "failed"
            raise
        finally:
            renderer.release_all()
            session.update(runs_rendered=renderer.rendered, finished=utc_now(),
                           notes=session["notes"] + take_rebuilt_notes())
            write_manifest(out_dir, plan, context, session)
            (out_dir / SPACE_RESERVE).unlink(missing_ok=True)
    return (1 if renderer.failed else 0), chosen


def _by_scene(plan: Plan) -> dict[tuple, list[RunSpec]]:
    groups: dict[tuple, list[RunSpec]] = {}
    for spec in plan.runs:
        if registry.get(spec.technique).tunable:
            groups.setdefault((spec.scene, spec.width, spec.height), []).append(spec)
    return groups


def _tune_scene(scene, specs: list[RunSpec], renderer: ViewRenderer, *, budget: int,
                seed: int, fixed: dict[str, set], say) -> list[Point]:
    where = f"{scene.name} {scene.width}x{scene.height}"
    moving = scene.frames > 1
    view = dataclasses.replace(scene.at_frame(0), name=f"{scene.name}.frame0") if moving else scene
    points = []
    for spec in specs:
        cls = registry.get(spec.technique)
        space = {n: d for n, d in cls.tunable.items() if n not in fixed.get(spec.technique, ())}
        label = point_label(cls, spec.params)
        # every tunable setting fixed by --set: the point's own setting is all there is to run
        search = Search(spec.params, space, budget if space else 1,
                        study_seed(seed, view.name, spec.technique, label))
        points.append(Point(spec, label, search))

    def on_view(spec: RunSpec, params: dict, tuning: str, target=view, frames=SEARCH_FRAMES,
                warmup=0) -> RunSpec:
        return dataclasses.replace(spec, scene=target.name, scene_key=target.key, params=params,
                                   frames=frames, warmup=warmup, tuning=tuning,
                                   tuned_on=view.name)

    limits = _baseline_runs(points, view, renderer, on_view, say, where)
    say(f"{where}: searching {len(points)} points of {len({p.spec.technique for p in points})} "
        f"techniques, at most {budget} settings each, on {view.name}")
    _search(points, view, renderer, on_view, limits, say, where)
    for point in points:
        point.best, point.met = point.search.best()
        if point.best is not None and not point.met:
            # a result, not progress: said under --quiet too
            print(f"{where}: {point.spec.technique} {point.label}: no setting meets acne <= "
                  f"{ACNE_LIMIT:g} % and leak <= {point.leak_limit:.3g} %; the closest kept "
                  f"(acne {point.best.acne_pct:.3g} %, leak {point.best.leak_pct:.3g} %)",
                  file=sys.stderr)
    chosen = [p for p in points if p.best is not None]
    if not moving:
        _held_out(chosen, scene, renderer, on_view, say, where)
    _windows(chosen, view, renderer, on_view, say, where)
    _timed(points, scene, renderer, on_view, say, where)
    return points


def _baseline_runs(points, view, renderer, on_view, say, where) -> dict:
    """The baseline at its defaults at each map size of the points, on the view; the leak limit
    of each map size (LEAK_MARGIN alone where no baseline is registered)."""
    specs = _baseline_specs(points, on_view, "baseline")
    if not specs:
        for point in points:
            point.leak_limit = LEAK_MARGIN
        return {}
    say(f"{where}: the baseline {registry.baseline()} at {len(specs)} map size(s): the leak "
        "limits")
    rows = renderer.render(view, list(specs.values()))
    limits = {}
    for size, spec in specs.items():
        leak = metric(rows[spec.run_id], "leak_pct")
        limits[size] = (leak if math.isfinite(leak) else 0.0) + LEAK_MARGIN
    for point in points:
        point.leak_limit = limits[point.spec.params.get(MAP_SIZE)]
    return limits


def _search(points, view, renderer, on_view, limits, say, where) -> None:
    """Rounds of one setting per point's search, each round rendered as one group."""
    from ..machine.interrupt import raise_if_interrupted

    started, round_number = time.perf_counter(), 0
    while True:
        raise_if_interrupted()
        asked = []
        for point in points:
            if point.search.done:
                continue
            technique = point.spec.technique
            params = point.search.ask(lambda p: validate_params(technique, p, "tune"))
            if params is not None:
                spec = on_view(point.spec, params, "search")
                asked.append((point, spec))
        if not asked:
            break
        round_number += 1
        extra = {spec.run_id: {"tune_point": point.label, "leak_limit": point.leak_limit}
                 for point, spec in asked}
        rows = renderer.render(view, [spec for _, spec in asked], extra)
        for point, spec in asked:
            point.search.tell(spec.params, rows[spec.run_id], point.leak_limit)
        say(f"{where}: search round {round_number}: {len(asked)} settings "
            f"({time.perf_counter() - started:.0f} s)")


def _baseline_specs(points, on_view, tuning: str, **timed) -> dict:
    """The baseline technique at its defaults at each map size of the points, by map size
    (none where no baseline is registered)."""
    name = registry.baseline()
    if name is None:
        return {}
    cls = registry.get(name)
    specs = {}
    for point in points:
        size = point.spec.params.get(MAP_SIZE)
        at_size = {MAP_SIZE: size} if size and MAP_SIZE in cls.Params.model_fields else {}
        base = dataclasses.replace(point.spec, technique=name, code_version=cls.code_version())
        specs[size] = on_view(base, validate_params(name, at_size, "tune"), tuning,
                              **({"frames": point.spec.frames, "warmup": point.spec.warmup,
                                  **timed} if timed else {}))
    return specs


def _baseline_at_defaults(points, scene, on_view, extra: dict) -> list[RunSpec]:
    """Where the baseline is not tuned itself, its timed runs at defaults at the points' map
    sizes: the cost the overview divides by at equal error."""
    name = registry.baseline()
    if name is None or any(point.spec.technique == name for point in points):
        return []
    specs = list(_baseline_specs(points, on_view, "defaults", target=scene).values())
    cls = registry.get(name)
    for spec in specs:
        extra[spec.run_id] = {"tune_point": point_label(cls, spec.params)}
    return specs


def _held_out(chosen, scene, renderer, on_view, say, where) -> None:
    """Each point's best setting and its defaults on the orbited view: over-tuning to the
    searched view shows there as a tuned error no better than the defaults'."""
    if not chosen:
        return
    view = scene.orbited(HELD_OUT_DEGREES, f"{scene.name}.orbit{HELD_OUT_DEGREES:g}")
    say(f"{where}: the best settings and the defaults on the held-out view {view.name}")
    specs = [(point, part, on_view(point.spec, params, "held_out", target=view))
             for point in chosen
             for part, params in (("best", point.best.params), ("defaults", point.spec.params))]
    extra = {spec.run_id: {"tune_point": point.label} for point, _, spec in specs}
    rows = renderer.render(view, [spec for _, _, spec in specs], extra)
    for point, part, spec in specs:
        point.held_out[part] = metric(rows[spec.run_id], "edge_mae")
    renderer.release(view.name)


def _window_point(points: list[Point]) -> Point:
    """The point of a technique whose knobs are at their defaults, else its first."""
    cls = registry.get(points[0].spec.technique)
    defaults = cls.Params().model_dump(mode="json")
    for point in points:
        if all(point.spec.params.get(k) == defaults.get(k) for k in cls.quality_knobs):
            return point
    return points[0]


def _windows(chosen, view, renderer, on_view, say, where) -> None:
    """Per technique, its window point's best setting with the bias terms scaled."""
    by_technique: dict[str, list[Point]] = {}
    for point in chosen:
        by_technique.setdefault(point.spec.technique, []).append(point)
    asked = []
    for technique, points in by_technique.items():
        cls = registry.get(technique)
        if not cls.bias_terms:
            continue
        point = _window_point(points)
        for scale in WINDOW_SCALES:
            try:
                params = validate_params(technique, scaled_bias(cls, point.best.params, scale),
                                         "tune")
            except cfg.ConfigError:  # a scale the technique refuses is no point of the curve
                continue
            asked.append((point, scale, on_view(point.spec, params, "window")))
    if not asked:
        return
    say(f"{where}: bias windows of {len({p.spec.technique for p, _, _ in asked})} techniques")
    # two scales saturated at a range's end give one setting (and run id): one row, the first
    extra = {}
    for point, scale, spec in asked:
        extra.setdefault(spec.run_id, {"tune_point": point.label, "bias_scale": scale,
                                       "leak_limit": point.leak_limit})
    unique = list({spec.run_id: spec for _, _, spec in asked}.values())
    rows = renderer.render(view, unique, extra)
    for point in {id(p): p for p, _, _ in asked}.values():
        mine = {spec.run_id: rows[spec.run_id] for p, _, spec in asked if p is point}
        ok = [r for r in mine.values() if r.get("status") == "ok"]
        scales = [metric(r, "bias_scale") for r in ok]
        point.window = bias_window(scales, [metric(r, "acne_pct") for r in ok],
                                   [metric(r, "leak_pct") for r in ok],
                                   leak_limit=point.leak_limit) if len(ok) > 1 else 0.0


def _timed(points, scene, renderer, on_view, say, where) -> None:
    """Each point at its defaults and at its best setting, timed, on the scene itself."""
    specs, extra, owner = [], {}, {}
    for point in points:
        common = {"tune_point": point.label, "leak_limit": point.leak_limit}
        if "defaults" in point.held_out:
            common["held_out_edge_mae"] = point.held_out["defaults"]
        timed = dict(target=scene, frames=point.spec.frames, warmup=point.spec.warmup)
        at_defaults = on_view(point.spec, point.spec.params, "defaults", **timed)
        specs.append(at_defaults)
        extra[at_defaults.run_id] = common
        owner[at_defaults.run_id] = (point, "defaults")
        if point.best is None:
            continue
        best = on_view(point.spec, point.best.params, "best", **timed)
        specs.append(best)
        extra[best.run_id] = {**common, "tuning_met": int(point.met),
                              "tuning_trials": len(point.search.tried),
                              "held_out_edge_mae": point.held_out.get("best", math.nan),
                              "bias_window": point.window}
        owner[best.run_id] = (point, "best")
    specs += _baseline_at_defaults(points, scene, on_view, extra)
    say(f"{where}: {len(specs)} runs at defaults and tuned, timed")
    rows = renderer.render(scene, specs, extra)
    for run_id, (point, part) in owner.items():
        point.timed = {**(point.timed or {}), part: rows[run_id]}
