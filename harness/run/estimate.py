"""What ``shadowbench plan`` says a plan's runs will take, from the runs stored in a folder.

A run's time is its frames' work plus what every run costs besides (its scene's pass, its
reference, scoring, storing). From the stored rows:

- **the cost of a frame**, per technique: ``ms = b * triangles + c * pixels`` (b, c >= 0), its
  cost per triangle and per pixel of a frame, fitted to the technique's stored runs by least
  squares in relative error (:func:`frame_costs`). A technique whose runs all have one ratio of
  triangles to pixels (one scene at one size) cannot tell the two apart: it takes the split of
  all techniques' runs together (each technique's times divided by their median, so none weighs
  more for being slow); where those cannot tell either, half per triangle and half per pixel at
  the stored runs' median. A technique with no stored run at all is priced at the median
  technique's level in that split.
- **the pace**, ``seconds = pace * frame work + per_run * runs``, a run's frame work being its
  frames and warm-up frames (the plan's warm-up: the stored rows do not say theirs) at its frame
  cost: what a frame costs beyond its measured time (the camera pass, the machine's load;
  ``pace`` >= 1) and what a run costs besides its frames (``per_run``: reference, scoring,
  storing), fitted to the folder's batches (the runs of one scene and size rendered together,
  each batch's wall time read from its rows' ``finished_at`` and the manifest's invocations;
  :func:`pace`). A folder of one batch gives the pace alone (its wall time over its work).

A planned run that is stored (same scene, size, technique and parameters) takes its stored
frame time; any other its technique's cost at its scene's triangles and pixels. Stored rows
without ``triangles`` (folders older than that column) count for the pace only.
"""

from __future__ import annotations

import itertools
import json
import statistics
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np

SPREAD = 1.5  # runs whose triangles-per-pixel vary less than this tell the two costs apart no better


def _nonnegative_least_squares(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """min |x c - y| with c >= 0, for a handful of columns: the best of the least-squares
    solutions on each subset of columns that come out non-negative (the optimum is one)."""
    best, best_residual = np.zeros(x.shape[1]), float(np.linalg.norm(y))
    for k in range(1, x.shape[1] + 1):
        for subset in itertools.combinations(range(x.shape[1]), k):
            c, *_ = np.linalg.lstsq(x[:, subset], y, rcond=None)
            if (c < 0).any():
                continue
            full = np.zeros(x.shape[1])
            full[list(subset)] = c
            residual = float(np.linalg.norm(x @ full - y))
            if residual < best_residual - 1e-12:
                best, best_residual = full, residual
    return best


def _fit(triangles, pixels, ms) -> np.ndarray | None:
    """(b, c) of ms = b * triangles + c * pixels in relative error; None when the points have
    one ratio of triangles to pixels (their costs cannot be told apart)."""
    triangles, pixels, ms = (np.asarray(v, float) for v in (triangles, pixels, ms))
    ratio = triangles / pixels
    if ratio.max() < SPREAD * ratio.min():
        return None
    x = np.column_stack([triangles, pixels]) / ms[:, None]
    return _nonnegative_least_squares(x, np.ones(len(ms)))


@dataclass
class FrameCosts:
    """Per technique, (ms per triangle, ms per pixel) of a frame, and how each was found."""

    per_unit: dict[str, np.ndarray]
    shape: np.ndarray  # the split of all techniques' runs, at the median technique's level
    how: dict[str, str] = field(default_factory=dict)  # "own", "shared split", "half and half"

    def ms(self, technique: str, triangles: int, pixels: int) -> float:
        b, c = self.per_unit.get(technique, self.shape)
        return float(b * triangles + c * pixels)


def frame_costs(rows: list[dict]) -> FrameCosts | None:
    """The cost of a frame per technique from the stored ok rows with a time and a triangle
    count (see the module); None without any."""
    points: dict[str, list[tuple[float, float, float]]] = {}
    for row in rows:
        try:
            t, w, h = float(row["triangles"]), float(row["width"]), float(row["height"])
            ms = float(row["time_ms"]) + float(row.get("setup_ms") or 0) / int(row["frames"])
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            continue
        if row.get("status") == "ok" and t > 0 and w * h > 0 and ms > 0:
            points.setdefault(row["technique"], []).append((t, w * h, ms))
    if not points:
        return None
    levels = {name: statistics.median(p[2] for p in ps) for name, ps in points.items()}
    level = statistics.median(levels.values())
    pooled = [(t, p, ms / levels[name]) for name, ps in points.items() for t, p, ms in ps]
    split = _fit(*zip(*pooled))
    if split is None or not split.any():  # one ratio everywhere: half of the median run per
        # triangle, half per pixel
        t0, p0 = (statistics.median(v) for v in list(zip(*pooled))[:2])
        split, shared = np.array([0.5 / t0, 0.5 / p0]), "half and half"
    else:
        shared = "shared split"
    per_unit, how = {}, {}
    for name, ps in points.items():
        own = _fit(*zip(*ps))
        if own is not None and own.any():
            per_unit[name], how[name] = own, "own"
        else:  # the shared split at this technique's level
            modelled = [split[0] * t + split[1] * p for t, p, _ in ps]
            scale = statistics.median(ms / m for (_, _, ms), m in zip(ps, modelled))
            per_unit[name], how[name] = split * scale, shared
    return FrameCosts(per_unit, split * level, how)


def _time(text: str) -> datetime | None:
    try:
        return datetime.fromisoformat(text)
    except (TypeError, ValueError):
        return None


def _work_seconds(row: dict, warmup: int = 0) -> float:
    """A stored run's frame work: (frames + ``warmup``) x time_ms, plus setup_ms; 0 for a run
    without a time (failed, skipped)."""
    try:
        frames = int(row["frames"]) + warmup
        return (frames * float(row["time_ms"]) + float(row.get("setup_ms") or 0)) / 1e3
    except (KeyError, TypeError, ValueError):
        return 0.0


def batches(rows: list[dict], manifest: dict, warmup: int = 0) -> list[tuple[float, float, int]]:
    """(wall seconds, frame work seconds, runs) of each batch of the folder: consecutive rows
    (by ``finished_at``) of one scene and size within one invocation, its wall time from the
    previous batch's end (or the invocation's start)."""
    out = []
    for session in manifest.get("invocations", []):
        start, end = _time(session.get("started")), _time(session.get("finished"))
        if start is None or end is None:
            continue
        mine = sorted(((t, row) for row in rows
                       if (t := _time(row.get("finished_at"))) is not None and start <= t <= end),
                      key=lambda tr: tr[0])
        previous = start
        for _, group in itertools.groupby(mine, key=lambda tr: (tr[1]["scene"], tr[1]["width"],
                                                                tr[1]["height"])):
            group = list(group)
            last = group[-1][0]
            out.append(((last - previous).total_seconds(),
                        sum(_work_seconds(row, warmup) for _, row in group), len(group)))
            previous = last
    return out


def _wall_seconds(manifest: dict) -> float:
    total = 0.0
    for session in manifest.get("invocations", []):
        start, end = _time(session.get("started")), _time(session.get("finished"))
        if start is not None and end is not None:
            total += (end - start).total_seconds()
    return total


def pace(rows: list[dict], manifest: dict, warmup: int = 0) -> tuple[float, float] | None:
    """(seconds of wall time per second of frame work, at least 1; seconds per run besides its
    frames) from the folder's batches, each run's frames counted with ``warmup`` more (the
    warm-up is not stored: the plan's is taken); None where the folder tells nothing (no wall
    time or no work)."""
    found = [b for b in batches(rows, manifest, warmup) if b[0] > 0 and b[1] > 0]
    if len(found) >= 2:
        wall, work, runs = (np.array(v, float) for v in zip(*found))
        # wall - work = (per_work - 1) work + per_run runs: a frame takes its own time at least
        extra, per_run = _nonnegative_least_squares(np.column_stack([work, runs]), wall - work)
        return 1.0 + float(extra), float(per_run)
    wall = _wall_seconds(manifest)
    work = sum(_work_seconds(row, warmup) for row in rows if row.get("status") == "ok")
    return (max(wall / work, 1.0), 0.0) if wall > 0 and work > 0 else None


@dataclass
class Estimate:
    seconds: float
    stored: int  # runs priced at their own stored time
    modelled: int  # runs priced by their scene's triangles and pixels
    how: str  # how the frame costs were found, for the line plan prints


def estimate(todo, triangles: dict[str, int], rows: list[dict], manifest: dict) -> Estimate | None:
    """Seconds for the planned runs ``todo`` (RunSpecs; ``triangles``: each scene's count) from
    a folder's stored ``rows`` and ``manifest`` (see the module); None where the folder has no
    run to price them from."""
    warmup = int(statistics.median(spec.warmup for spec in todo)) if todo else 0
    speed = pace(rows, manifest, warmup)
    costs = frame_costs(rows)
    if speed is None:
        return None
    per_work, per_run = speed
    ok = {(r["scene"], str(r["width"]), str(r["height"]), r["technique"],
           json.dumps(json.loads(r["params"] or "{}"), sort_keys=True)): r
          for r in rows if r.get("status") == "ok" and _work_seconds(r) > 0}
    seconds, stored, modelled = 0.0, 0, 0
    for spec in todo:
        row = ok.get((spec.scene, str(spec.width), str(spec.height), spec.technique,
                      spec.params_json))
        if row is not None:
            stored += 1
            frame = _work_seconds(row) / max(int(row["frames"]), 1)
        elif costs is not None:
            modelled += 1
            frame = costs.ms(spec.technique, triangles[spec.scene], spec.width * spec.height) / 1e3
        else:
            return None
        seconds += per_work * frame * (spec.frames + spec.warmup) + per_run
    kinds = sorted(set(costs.how.values())) if costs is not None else []
    unstored = sorted({spec.technique for spec in todo} - set(costs.per_unit)) if costs else []
    how = "; ".join(filter(None, [
        kinds and "cost per triangle and per pixel " + ", ".join(
            {"own": "fitted to each technique's runs", "shared split": "split as all "
             "techniques' runs split it", "half and half": "half and half (the stored runs "
             "have one size: they cannot tell)"}[k] for k in kinds),
        unstored and f"{', '.join(unstored)} not stored: at the median technique's cost"]))
    return Estimate(seconds, stored, modelled, how)


def duration(seconds: float) -> str:
    """``12 s``, ``4 min 12 s``, ``104 h 12 min``."""
    seconds = round(seconds)
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        return f"{hours} h {minutes} min"
    return f"{minutes} min {secs} s" if minutes else f"{secs} s"
