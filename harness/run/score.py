"""Scoring, below measuring: a measured run (its spec, row, pass meter and last output) and
its frame's reference become the row's columns (cost, timing, metrics) and its stored arrays."""

from __future__ import annotations

import contextlib
import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..analysis import cost_model
from ..truth import metrics
from .. import results
from ..gl.measure import COUNTERS
from ..machine.timing import NOISY_CONTENTION, median_interval
from .plan import RunSpec


def one_line(e: BaseException) -> str:
    return f"{type(e).__name__}: {' '.join(str(e).split())}"[:500]


def _run_columns(spec: RunSpec) -> dict:
    return {"run_id": spec.run_id, "schema": results.SCHEMA_VERSION, "scene": spec.scene,
            "technique": spec.technique, "params": spec.params_json, "width": spec.width,
            "height": spec.height, "map_res": spec.params.get("res"), "frames": spec.frames,
            "code_version": spec.code_version, "ref_samples": spec.samples,
            "cost": spec.cost, "tuning": spec.tuning, "tuned_on": spec.tuned_on}


def failed_scene_row(spec: RunSpec, error: Exception) -> dict:
    """The row of a run whose scene could not be prepared (its reference or its frame failed):
    the scene's failure is its runs' error rows, not the end of the sweep."""
    return {**_run_columns(spec), "status": "error",
            "error": f"scene {spec.scene} {spec.width}x{spec.height}: {one_line(error)}"}


def first_columns(spec: RunSpec, reference, scene_ms: float, frags_scene: int,
                   renderer: str) -> dict:
    return {**_run_columns(spec), "scene_ms": scene_ms, "frags_scene": frags_scene,
            "renderer": renderer, "ref_seconds": reference.seconds,
            "ref_build_seconds": reference.build_seconds}


def _timing_columns(timed) -> dict:
    """Median frame time with its interval, per-pass times and work counters, machine load;
    under ``cost: static`` the setup's median time and interval (``setup_ms``), empty under
    ``dynamic``, where every frame holds the setup's work."""
    meter, method = timed.meter, timed.spec.statistics
    totals = meter.frame_totals_ms
    time_ms, low, high = median_interval(totals, method=method)
    passes = meter.passes(method)
    load = meter.cpu_contention
    setup = (median_interval(timed.setup.frame_totals_ms, method=method)
             if timed.setup is not None else (None, None, None))
    return dict(
        setup_ms=setup[0], setup_ms_ci_low=setup[1], setup_ms_ci_high=setup[2],
        time_ms=time_ms, time_ms_ci_low=low, time_ms_ci_high=high, time_ms_min=min(totals),
        time_ms_max=max(totals), frame_ms=[round(t, 4) for t in totals],
        cpu_contention=None if load is None else round(load, 4),
        noisy=None if load is None else int(load > NOISY_CONTENTION),
        **{c: sum(getattr(p, c) for p in passes) if meter.counts else None for c in COUNTERS},
        passes=[{"name": p.name, "ms": round(p.ms, 4), "ms_ci_low": round(p.ms_ci_low, 4),
                 "ms_ci_high": round(p.ms_ci_high, 4), "fragments": p.fragments,
                 **({c: getattr(p, c) for c in COUNTERS} if meter.counts else {})}
                for p in passes])


def _cost_columns(timed, frame) -> dict:
    """Timing, counters, fill, memory and the range of V, from the run's last frame, and the
    scene's family (empty for a scene of objects) and counts (triangles, parts, open parts,
    shadow edges from that frame's light), and what its mesh files skipped."""
    row, output = timed.row, timed.output
    v = output.visibility
    family = frame.scene.config.family
    columns = {**_timing_columns(timed), **frame.scene.counts,
               "family": family.kind if family else ""}
    frags_shadow = (output.shadow_fragments if output.shadow_fragments is not None
                    else sum(p["fragments"] for p in columns["passes"]))
    columns.update(
        frags_shadow=frags_shadow, overdraw=frags_shadow / max(row["frags_scene"], 1),
        mem_bytes=output.mem_bytes, fetches_per_px=output.fetches_per_px,
        covered_px=int(frame.arrays.covered.sum()),
        nonfinite=output.nonfinite + metrics.nonfinite(v),
        v_min=float(np.nanmin(v)) if v.size else None,
        v_max=float(np.nanmax(v)) if v.size else None,
        mesh_notes=frame.scene.mesh_notes,
        warnings="; ".join(output.warnings + ([row["warnings"]] if "warnings" in row else [])),
    )
    return columns


def _clean(v: np.ndarray) -> np.ndarray:
    """V as the metrics see it: NaN half lit, infinities clipped."""
    return np.nan_to_num(v, nan=0.5, posinf=1.0, neginf=0.0)


@dataclass
class FrameTruth:
    """A frame's reference as the metrics see it, shared by the runs scored against it: the
    compared pixels, V_ref in float64 and its edge band."""

    index: int  # the frame of the sequence (0 for a still scene)
    reference: object  # harness.truth.reference.Reference
    mask: np.ndarray  # Frame.compared_pixels

    def __post_init__(self):
        self.visibility = self.reference.visibility.astype(np.float64)
        self.band = metrics.edge_band(self.visibility, mask=self.mask)
        self.edge_floor = metrics.edge_floor(self.visibility, mask=self.mask, band=self.band)


def _metric_columns(v_clean: np.ndarray, frame, truth: FrameTruth) -> tuple[dict, dict]:
    """The error metrics of one frame's V against its reference on the compared pixels, and
    the shaded images where the scene asks for shading."""
    v, ref_v, mask, band = v_clean.astype(np.float64), truth.visibility, truth.mask, truth.band
    columns = dict(
        mae=metrics.mae(v, ref_v, mask=mask),
        rmse=metrics.rmse(v, ref_v, mask=mask),
        wrong_pct=metrics.wrong_pct(v, ref_v, mask=mask),
        edge_mae=metrics.edge_mae(v, ref_v, mask=mask, band=band),
        levels=metrics.levels(v, ref_v, mask=mask, band=band),
        ssim=metrics.ssim(v, ref_v, mask=mask),
        psnr=metrics.psnr(v, ref_v, mask=mask),
        acne_pct=metrics.acne_pct(v, ref_v, mask=mask, band=band),
        leak_pct=metrics.leak_pct(v, ref_v, mask=mask, band=band),
        edge_floor=truth.edge_floor,
    )
    # edge_mae as a multiple of the best a 0/1 answer can do; empty where that best is 0
    floor = truth.edge_floor
    columns["edge_ratio"] = columns["edge_mae"] / floor if floor > 0 else None
    reference, images = truth.reference, {}
    if reference.direct is not None:
        a = frame.arrays
        ambient = frame.scene.config.ambient
        shaded = metrics.shade(v_clean, a.normal, a.position, a.albedo, frame.scene.light,
                               ambient=ambient)
        shaded_ref = reference.direct + (ambient * a.albedo)[..., None]
        columns["flip"] = metrics.flip(shaded, shaded_ref)
        # grey images (one channel) for the report's viewer; float16 is plenty to look at
        images["shaded"] = shaded[..., 0].astype(np.float16)
        images["shaded_reference"] = shaded_ref.mean(-1).astype(np.float16)
    return columns, images


def _frame_arrays(output, frame, truth: FrameTruth, images: dict) -> dict[str, np.ndarray]:
    """V, coverage, the compared pixels, the shaded images and the technique's diagnostic maps
    of one frame, as a run stores them."""
    return {"visibility": output.visibility.astype(np.float32), "covered": frame.arrays.covered,
            "compared": truth.mask, **images,
            **{f"map_{name}": np.asarray(m, np.float32) for name, m in output.maps.items()}}


@contextlib.contextmanager
def _warnings_into(row: dict):
    """Warnings raised while a run is scored concern its numbers: into its ``warnings``
    column (each message once), never onto the terminal."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    messages = dict.fromkeys(f"{w.category.__name__}: {' '.join(str(w.message).split())}"
                             for w in caught)
    if messages:
        row["warnings"] = "; ".join(filter(None, [row.get("warnings"), *messages]))


def score_run(timed, frame, reference) -> tuple[dict, dict[str, np.ndarray]]:
    """The finished run's row (timing, counters, metrics) and arrays, from its last frame."""
    with _warnings_into(timed.row):
        return _score_row(timed, frame, reference)


def _complete(row: dict) -> None:
    """A scored row's last columns: the GPU estimate, priced once the technique's own columns
    (its traversal counts among them) are in the row, and the status."""
    row["gpu_estimate_ms"] = cost_model.estimate_ms(row)
    row["status"] = "ok"


def _score_row(timed, frame, reference) -> tuple[dict, dict[str, np.ndarray]]:
    row, output = timed.row, timed.output
    row.update(_cost_columns(timed, frame))
    truth = FrameTruth(0, reference, frame.compared_pixels(reference.covered))
    columns, images = _metric_columns(_clean(output.visibility), frame, truth)
    row.update(columns)
    row.update(output.extra)
    _complete(row)
    return row, _frame_arrays(output, frame, truth, images)


# --- moving scenes ----------------------------------------------------------------------------

# A moving run stores, besides frame 0's arrays and its per-frame series, its worst frame's
# V, reference and error and a strip of STRIP_RADIUS frames either side of it.
STRIP_RADIUS = 2
# The worst frame of a sequence's metrics: the largest of each; of ssim and psnr the smallest;
# none of levels (not an error) and edge_floor (the reference's, not the technique's).
WORST_IS_LOWEST = ("ssim", "psnr")
NO_WORST = ("levels", "edge_floor")


@dataclass
class SequenceState:
    """What a run on a moving scene keeps across frames: per-frame values, its previous V
    (for flicker) with that frame's depth and camera (for world flicker), frame 0's arrays,
    the worst frame so far and the strip around it. Memory stays a few images per run however
    long the sequence."""

    series: dict[str, list] = field(default_factory=dict)
    extras: dict[str, list] = field(default_factory=dict)  # the technique's columns per frame
    previous: np.ndarray | None = None
    previous_depth: np.ndarray | None = None  # metrics.view_depth of the previous frame
    previous_view_proj: np.ndarray | None = None
    first: dict | None = None  # frame 0's arrays
    # (t, V, V_ref, coverage) of the last STRIP_RADIUS frames
    recent: list = field(default_factory=list)
    worst_key: tuple = (-math.inf, -math.inf)
    worst: dict | None = None
    strip: list = field(default_factory=list)  # (t, V, V_ref, coverage) around the worst frame
    strip_wanted: int = 0  # frames after the worst still to join the strip
    nonfinite: int = 0
    v_range: tuple = (math.inf, -math.inf)

    def add(self, name: str, value) -> None:
        self.series.setdefault(name, []).append(value)


def observe_frame(timed, frame, truth: FrameTruth, previous: FrameTruth | None) -> None:
    """Score frame ``truth.index`` of a run on a moving scene into its :class:`SequenceState`."""
    sequence = timed.sequence = timed.sequence or SequenceState()
    output, t, covered = timed.output, truth.index, frame.arrays.covered
    v = _clean(output.visibility)
    ref_v = truth.reference.visibility
    columns, images = _metric_columns(v, frame, truth)
    for name, value in columns.items():
        sequence.add(name, value)
    flicker = (math.nan if previous is None else
               metrics.flicker(v, sequence.previous, ref_v, previous.reference.visibility,
                               mask=truth.mask, mask_previous=previous.mask))
    sequence.add("flicker", flicker)
    _observe_world_flicker(sequence, v, frame, truth, previous)
    for name, value in output.extra.items():
        sequence.extras.setdefault(name, []).append(value)
    sequence.nonfinite += output.nonfinite + metrics.nonfinite(output.visibility)
    if output.visibility.size:
        low, high = sequence.v_range
        sequence.v_range = (min(low, float(np.nanmin(output.visibility))),
                            max(high, float(np.nanmax(output.visibility))))
    if t == 0:
        sequence.first = _frame_arrays(output, frame, truth, images)
    # the worst frame: the largest flicker (a pop), the largest mae among equals
    key = (0.0 if math.isnan(flicker) else flicker,
           -math.inf if math.isnan(columns["mae"]) else columns["mae"])
    if key > sequence.worst_key:
        sequence.worst_key = key
        error = np.where(truth.mask, np.abs(v - ref_v), np.nan).astype(np.float32)
        sequence.worst = dict(worst_frame=np.int64(t), worst_visibility=v.astype(np.float32),
                              worst_reference=ref_v, worst_error=error, worst_covered=covered)
        sequence.strip = sequence.recent + [(t, v, ref_v, covered)]
        sequence.strip_wanted = STRIP_RADIUS
    elif sequence.strip_wanted:
        sequence.strip.append((t, v, ref_v, covered))
        sequence.strip_wanted -= 1
    sequence.recent = (sequence.recent + [(t, v, ref_v, covered)])[-STRIP_RADIUS:]
    sequence.previous = v


def _observe_world_flicker(sequence: SequenceState, v: np.ndarray, frame, truth: FrameTruth,
                           previous: FrameTruth | None) -> None:
    """Frame ``truth.index``'s world flicker and changed % (NaN at frame 0) into the sequence's
    series, then this frame's depth and camera kept for the next. A moving object's pixels are
    not left out (the frame does not say which moved): :func:`harness.truth.metrics.world_points`'
    depth test drops those that left their place in depth."""
    a = frame.arrays
    world_flicker = changed = math.nan
    if previous is not None:
        points = metrics.world_points(a.position, sequence.previous_view_proj,
                                      sequence.previous_depth, mask=truth.mask,
                                      mask_previous=previous.mask)
        world_flicker = metrics.world_flicker(v, sequence.previous, truth.reference.visibility,
                                              previous.reference.visibility, points=points)
        changed = metrics.world_changed_pct(v, sequence.previous, points=points)
    sequence.add("world_flicker", world_flicker)
    sequence.add("world_changed_pct", changed)
    sequence.previous_depth = metrics.view_depth(a.position, frame.camera.view_proj)
    sequence.previous_view_proj = frame.camera.view_proj


def sequence_score(timed, frame) -> tuple[dict, dict[str, np.ndarray]]:
    """A moving run's row and arrays: metrics as the mean over frames and their worst frame,
    flicker, pop frames; costs from the last frame, timing over the sequence's frames."""
    with _warnings_into(timed.row):
        return _sequence_row(timed, frame)


def _sequence_row(timed, frame) -> tuple[dict, dict[str, np.ndarray]]:
    row, sequence = timed.row, timed.sequence
    row.update(_cost_columns(timed, frame))
    series = {name: np.asarray(values, np.float64) for name, values in sequence.series.items()}
    flicker = series.pop("flicker")
    with warnings.catch_warnings():  # a metric NaN in every frame stays NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        for name, values in series.items():
            row[name] = float(np.nanmean(values))
            if name in WORST_IS_LOWEST:
                row[f"{name}_min"] = float(np.nanmin(values))
            elif name not in NO_WORST:
                row[f"{name}_max"] = float(np.nanmax(values))
        row.update(flicker=float(np.nanmean(flicker[1:])),
                   flicker_max=float(np.nanmax(flicker[1:])))
    row.update(pop_frames=metrics.pop_frames(flicker[1:]),
               worst_frame=int(sequence.worst["worst_frame"]), nonfinite=sequence.nonfinite,
               v_min=sequence.v_range[0], v_max=sequence.v_range[1])
    for name, values in sequence.extras.items():  # the technique's columns
        if all(isinstance(x, (int, float, np.number)) for x in values):  # bools count too
            series[f"extra_{name}"] = np.asarray(values, np.float64)
            row[name] = float(np.mean(series[f"extra_{name}"]))
        else:
            row[name] = values[-1]
    _complete(row)
    strip_frames, strip_v, strip_ref, strip_covered = zip(*sequence.strip)
    arrays = {**sequence.first, **sequence.worst,
              **{f"series_{name}": values for name, values in series.items()},
              "series_flicker": flicker,
              "series_frame_ms": np.asarray(timed.meter.frame_totals_ms, np.float64),
              "strip_frames": np.asarray(strip_frames, np.int64),
              "strip_visibility": np.stack(strip_v).astype(np.float32),
              "strip_reference": np.stack(strip_ref).astype(np.float32),
              "strip_covered": np.stack(strip_covered)}
    return row, arrays
