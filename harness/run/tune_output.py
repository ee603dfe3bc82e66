"""What ``shadowbench tune`` hands back besides the rows: DIR/tuned.yaml, an experiment that
runs the settings chosen (``shadowbench run DIR/tuned.yaml``; each grid's ``set:`` can be
copied into another experiment), and the summary lines the command prints."""

from __future__ import annotations

import math
import os
from pathlib import Path

import yaml

from .. import results
from ..technique import registry
from .tune_search import metric

TUNED_FILE = "tuned.yaml"


def _setting(point) -> dict:
    """A point's ``set:``: its quality knobs, every setting searched as chosen, and whatever
    else differs from the defaults (the experiment's and --set's fixed values)."""
    cls = registry.get(point.spec.technique)
    params = point.best.params
    defaults = cls.Params().model_dump(mode="json")
    names = ([k for k in cls.quality_knobs if k in params] + list(point.search.space)
             + [k for k in params if params[k] != defaults.get(k)])
    return {name: params[name] for name in dict.fromkeys(names) if name in params}


def tuned_experiment(chosen: dict, plan) -> dict:
    """The experiment of the settings chosen: per scene (``per_scene:``), per technique one
    grid per point, ``set:`` to its setting; the plan's scene file, frames and image size."""
    per_scene, techniques, sizes, scenes, triangles = {}, {}, set(), [], []
    frames = warmup = None
    for (scene_name, width, height), points in chosen.items():
        grids: dict[str, list] = {}
        for point in points:
            if point.best is None:
                continue
            grids.setdefault(point.spec.technique, []).append({"set": _setting(point)})
            techniques.setdefault(point.spec.technique, {})
            frames, warmup = point.spec.frames, point.spec.warmup
        if not grids:
            continue
        per_scene[scene_name] = {"techniques": grids}
        base, _, size = scene_name.partition("@")
        scenes.append(base)
        if size:
            triangles.append(float(size))
        own = plan.scenes[scene_name].config.resolution
        if (width, height) != tuple(own):
            sizes.add((width, height))
    experiment: dict = {}
    source = next((source for _, _, source in plan.described() if source is not None), None)
    if source is not None:
        experiment["scene_file"] = str(source.resolve())
    experiment["scenes"] = list(dict.fromkeys(scenes))
    if triangles:
        experiment["triangles"] = sorted(set(triangles))
    if sizes:
        experiment["resolutions"] = [list(s) for s in sorted(sizes)]
    if frames is not None and not any(plan.scenes[n].frames > 1 for n in per_scene):
        experiment.update(frames=frames, warmup=warmup)
    experiment["techniques"] = techniques
    experiment["per_scene"] = per_scene
    return experiment


def write_tuned(out_dir: str | Path, chosen: dict, plan, *, budget: int, seed: int) -> Path | None:
    """DIR/tuned.yaml (replaced whole); None when no setting was chosen."""
    experiment = tuned_experiment(chosen, plan)
    if not experiment["per_scene"]:
        return None
    if "scene_file" in experiment:  # relative to this file, as an experiment's scene_file is
        experiment["scene_file"] = os.path.relpath(experiment["scene_file"],
                                                   Path(out_dir).resolve())
    head = (f"# The settings shadowbench tune chose (budget {budget}, seed {seed}), per scene and "
            "point of each\n# technique's quality curve. Run them: shadowbench run "
            f"{Path(out_dir) / TUNED_FILE} --out DIR\n# or copy a grid's set: into an "
            "experiment (docs/fairness.md).\n")
    text = head + yaml.safe_dump(experiment, sort_keys=False, default_flow_style=None, width=100)
    path = Path(out_dir) / TUNED_FILE
    results.replace_atomically(path, lambda f: f.write(text.encode("utf-8")))
    return path


def _changed(point) -> str:
    """The settings the search changed from the point's own, ``name=value``."""
    best = point.best.params
    changed = [f"{name}={_show(best[name])}" for name in point.search.space
               if best.get(name) != point.spec.params.get(name)]
    return " ".join(changed) or "(its defaults)"


def _show(value) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _number(value: float, digits: int = 3) -> str:
    return f"{value:.{digits}g}" if math.isfinite(value) else "-"


def summary_lines(chosen: dict) -> list[str]:
    """Per scene a table: each point's edge_mae at defaults and tuned (timed runs), the gain,
    the tuned acne and leak against the limits (searched view), the held-out edge_mae, the
    bias window and the setting chosen."""
    lines = []
    for (scene_name, width, height), points in chosen.items():
        lines.append(f"{scene_name} {width}x{height}:")
        wide = max(len(p.label) for p in points) + 2
        lines.append(f"  {'technique':<11}{'point':<{wide}}{'edge_mae defaults -> tuned':<28}"
                     f"{'gain':<7}{'acne %':<8}{'leak % (limit)':<16}"
                     f"{'held out: defaults -> tuned':<29}{'window':<8}setting")
        for point in points:
            name = point.spec.technique
            if point.best is None:
                lines.append(f"  {name:<11}{point.label:<{wide}}no setting ran (see the rows' "
                             "error)")
                continue
            held = point.held_out
            held_text = (f"{_number(held.get('defaults', math.nan), 4)} -> "
                         f"{_number(held.get('best', math.nan), 4)}" if held else "-")
            timed = point.timed or {}
            at_defaults = metric(timed.get("defaults", {}), "edge_mae")
            tuned = metric(timed.get("best", {}), "edge_mae")
            gain = at_defaults / tuned if tuned > 0 else math.nan
            flag = "" if point.met else "  (limits not met: the closest)"
            leak = f"{_number(point.best.leak_pct, 2)} ({_number(point.leak_limit, 2)})"
            lines.append(
                f"  {name:<11}{point.label:<{wide}}"
                f"{_number(at_defaults, 4) + ' -> ' + _number(tuned, 4):<28}"
                f"{_number(gain) + 'x':<7}{_number(point.best.acne_pct, 2):<8}{leak:<16}"
                f"{held_text:<29}{_number(point.window, 2):<8}{_changed(point)}{flag}")
    return lines
