"""Measuring, after planning and above scoring: the runs of one scene and resolution,
prepared in batches, render their measured frames in interleaved rounds (moving: frame by frame).

The run's cost policy (``RunSpec.cost``) says what a frame is. ``dynamic``: the technique's
``update`` (the work that depends on the light and the geometry) and its ``render`` (the
per-view work), both in every frame, warm-up and measured. ``static``: ``update`` is the
run's setup, timed apart (repeated over the same warm-up and measured frames as the frames
themselves, its own pass record), and every frame is ``render`` alone."""

from __future__ import annotations

import os
import time
import traceback
from dataclasses import dataclass

import numpy as np

from ..technique import registry
from ..machine import interrupt
from ..machine.memory import PeakWatch, resident_bytes, trim_heap
from ..machine.timing import cpu_sample, others_time
from .plan import RunSpec
from .score import (FrameTruth, SequenceState, first_columns, observe_frame, one_line, score_run,
                    sequence_score)

# Runs of one scene and resolution are measured in interleaved rounds (each round renders one
# measured frame of every run of a batch), so a burst of load from other processes spreads
# over all of them instead of landing on one. A batch keeps its runs prepared at once, so it
# closes when its runs' maps (their mem_bytes, known after the first frame) reach
# BATCH_BYTES or it holds BATCH_RUNS runs: memory stays within about one batch (a 4096^2
# float map is 64 MiB) whatever the sweep. At 10^6 triangles a prepared run also holds
# buffers the size of the scene that its mem_bytes leaves out (sv's edge quads: 0.6 GiB on
# instancing@1e6), and its prepare passes through more (sv's: 2.1 GiB over what it keeps), so
# the batch follows the resident memory its runs really take: it takes no run whose start
# (prepare and warm-up), at the peak its technique showed (:class:`Footprints`), would take
# the process more than BATCH_RESIDENT over where the batch began. A run over that alone
# starts a batch of its own. Issue 53: make scale peaked at 5.2 GiB with three sv runs of
# instancing@1e6 prepared while a fourth prepared.
BATCH_BYTES = 256 * 2**20
BATCH_RUNS = 16
BATCH_RESIDENT = int(1.5 * 2**30)
# A batch whose first run is expected to pass through this much starts on a GL context made
# anew (``Frame.renew_context``): llvmpipe keeps what its draws of a large scene allocated
# until its context goes (0.3 GiB after silhouette's three runs of instancing@1e6), and such a
# run should not find the batches before it there.
RENEW_BYTES = 256 * 2**20
# What a technique never seen in this process is assumed to pass through at its start, per
# triangle of the scene: about sv's at 10^6 (2.1 GiB on instancing@1e6), the most of any
# technique shipped. At 10^3 that is 2.4 MiB: only a large scene makes such a run wait.
UNSEEN_BYTES_PER_TRIANGLE = 2560


@dataclass
class _Timed:
    """A run between prepare and release: its row so far, technique, pass record and the
    output of its last frame."""

    spec: RunSpec
    row: dict
    meter: object  # harness.gl.measure.PassMeter, the run's own
    setup: object = None  # under cost: static, the PassMeter of its update's repeats
    technique: object = None
    output: object = None  # harness.technique.ShadowOutput
    measured: int = 0  # measured frames rendered so far
    sequence: "SequenceState | None" = None  # a moving scene's run: what it keeps across frames

    @property
    def alive(self) -> bool:
        return "status" not in self.row

    @property
    def updates_per_frame(self) -> bool:
        return self.spec.cost == "dynamic"


def _render(timed: _Timed, frame, measuring: bool) -> None:
    """One frame of the run: under ``cost: dynamic`` the technique's update and its render,
    under ``static`` its render (its update is the setup, :func:`_measure_setup`)."""
    from ..technique import reset_gl_state

    try:
        with frame.metered(timed.meter):
            timed.meter.new_frame(measuring)
            if timed.updates_per_frame:
                timed.technique.update(frame)
            timed.output = timed.technique.render(frame)
        timed.measured += measuring
    finally:
        reset_gl_state()  # each run's frame starts from the state the harness assumes


def _release(timed: _Timed) -> None:
    from ..technique import reset_gl_state

    if timed.technique is not None:
        try:
            timed.technique.release()
        except Exception as e:  # the run's result stands; a failed release only leaks
            timed.row["warnings"] = f"release failed: {one_line(e)}"
        timed.technique = None
    timed.meter.release()
    if timed.setup is not None:
        timed.setup.release()
    reset_gl_state()


def _attempt(timed: _Timed, step, *args) -> bool:
    """``step(*args)``; a technique's failure ends its run (status and error in its row,
    resources released), never the sweep."""
    from ..technique import NotApplicable

    try:
        step(*args)
        return True
    except NotApplicable as e:
        timed.row.update(status="skipped", error=str(e))
    except Exception as e:  # a technique's failure is its row's, not the sweep's
        timed.row.update(status="error", error=one_line(e))
        if os.environ.get("SHADOWBENCH_DEBUG"):
            traceback.print_exc()
    _release(timed)
    return False


def _measure_setup(timed: _Timed, frame) -> None:
    """Under ``cost: static``: the technique's update, the work done once for the fixed light
    and geometry, repeated over the run's warm-up and measured frames into a pass record of
    its own (each call redoes the work and leaves the same state)."""
    from ..technique import reset_gl_state

    timed.setup = frame.new_meter()
    warmup = timed.spec.warmup
    for i in range(warmup + timed.spec.frames):
        try:
            with frame.metered(timed.setup):
                timed.setup.new_frame(i >= warmup)
                timed.technique.update(frame)
        finally:
            reset_gl_state()


def _prepare_ms(technique, frame) -> float:
    """Run the technique's ``prepare`` and return its wall time in ms, GL work included
    (glFinish on both sides): the one-off work an engine does at load time (edge meshes,
    bottom-level BVHs, buffers, shaders), reported as ``prepare_ms`` and charged in no frame
    under either cost policy."""
    from OpenGL import GL

    GL.glFinish()
    start = time.perf_counter()
    technique.prepare(frame)
    GL.glFinish()
    return round((time.perf_counter() - start) * 1e3, 3)


def _start(spec: RunSpec, frame, row: dict) -> _Timed:
    """Prepare the run (under ``cost: static``, measure its setup) and render its warm-up
    frames (with no warm-up, its first measured frame; on a moving scene, one unmeasured
    frame): its map bytes are then known."""
    cls = registry.get(spec.technique)
    timed = _Timed(spec, row, frame.new_meter())
    moving = frame.frames > 1
    warmup = max(spec.warmup, 1) if moving else spec.warmup

    def prepare():
        cls.check_light(frame.scene.light)
        params = cls.Params(**spec.params)
        timed.row["alpha"] = cls.alpha_handling(params, frame.scene)
        cls.check_alpha(params, frame.scene)
        timed.technique = cls(params)
        timed.row["prepare_ms"] = _prepare_ms(timed.technique, frame)
        if not timed.updates_per_frame:
            _measure_setup(timed, frame)
        for _ in range(warmup):
            _render(timed, frame, measuring=False)

    if _attempt(timed, prepare) and warmup == 0:
        _measure_round([timed], frame, 0)
    return timed


def _measure_round(batch: list[_Timed], frame, turn: int) -> None:
    """One measured frame of each run, starting
    at a position that turns each round (no run always follows the same one). The CPU time
    other processes used during the round is attributed to each run in proportion to its
    share of the round's wall time."""
    order = batch[turn % len(batch):] + batch[:turn % len(batch)]
    walls = []
    before, began = cpu_sample(), time.perf_counter()
    for timed in order:
        start = time.perf_counter()
        if _attempt(timed, _render, timed, frame, True):
            walls.append((timed, time.perf_counter() - start))
    round_s, after = time.perf_counter() - began, cpu_sample()
    if before is None or after is None or round_s <= 0:
        return
    others_s, capacity_s = others_time(before, after)
    for timed, wall in walls:
        timed.meter.add_load(others_s * wall / round_s, capacity_s * wall / round_s)


def return_freed_memory() -> None:
    """Give back what a finished scene's group freed, before the next scene: glibc keeps what
    numpy's scene-sized temporaries (edges, volumes, maps read back) and the driver's threads
    freed in its heaps and per-thread arenas, so a sweep's resident memory grew from scene to
    scene (4 families at 10^6, sm and silhouette: 1.24 GiB between groups, 0.74 with this).
    Arrays held only by reference cycles are collected first, Dr.Jit's cache of freed blocks
    flushed (where a reference or a technique loaded it) and llvmpipe's last bindings let go
    (:func:`_return_batch_memory`)."""
    import gc
    import sys

    gc.collect()
    if "drjit" in sys.modules:
        sys.modules["drjit"].flush_malloc_cache()
    _return_batch_memory()


def _return_batch_memory() -> None:
    """What a batch's released runs freed, back to the system before the next batch prepares:
    the driver's hold on their last-bound textures and buffers (where this process has a GL
    context; ``harness.gl.objects.drop_stale_bindings``), then the heap's free pages."""
    from ..gl import context

    if context.current() is not None:
        from ..gl.objects import drop_stale_bindings

        drop_stale_bindings()
    trim_heap()


def _renew_context(frame) -> bool:
    """The frame on a GL context made anew, where this process has one and nothing but the
    frame lives in it, then the heap trimmed; whether it was."""
    from ..gl import context

    renewed = context.current() is not None and frame.renew_context(context.current())
    if renewed:
        trim_heap()
    return renewed


class Footprints:
    """What each technique's runs passed through as they started (prepare, static setup,
    warm-up): the peak resident memory over what the process held just before, the most any
    of its runs took on each scene (scene key and size) it ran on, with that scene's
    triangles. :meth:`predict` gives a run's from its technique's on the same scene; else the
    most of what it took on other scenes of as many triangles and of what its smaller scenes
    give, grown with the triangles (along the line through the two largest sizes, the most
    of any scene at each: a map's bytes stay, an edge buffer's grow; from one size, by
    UNSEEN_BYTES_PER_TRIANGLE for each triangle more); else UNSEEN_BYTES_PER_TRIANGLE for
    each triangle."""

    def __init__(self):
        self.seen: dict[str, dict[tuple, tuple[int, int]]] = {}

    def observe(self, technique: str, scene: tuple, triangles: int, peak_bytes: int) -> None:
        scenes = self.seen.setdefault(technique, {})
        scenes[scene] = (triangles, max(scenes.get(scene, (0, 0))[1], peak_bytes, 0))

    def predict(self, technique: str, scene: tuple, triangles: int) -> int:
        scenes = self.seen.get(technique, {})
        if scene in scenes:
            return scenes[scene][1]
        by_size: dict[int, int] = {}
        for size, peak in scenes.values():
            if size <= triangles:
                by_size[size] = max(by_size.get(size, 0), peak)
        guesses = [by_size.pop(triangles)] if triangles in by_size else []
        sizes = sorted(by_size)
        if len(sizes) == 1:  # what it took there, the more triangles as an unseen one's
            guesses.append(by_size[sizes[0]] + UNSEEN_BYTES_PER_TRIANGLE * (triangles - sizes[0]))
        elif sizes:
            (small, low), (large, high) = [(size, by_size[size]) for size in sizes[-2:]]
            guesses.append(round(high + max(high - low, 0) / (large - small)
                                 * (triangles - large)))
        return max(guesses) if guesses else UNSEEN_BYTES_PER_TRIANGLE * triangles


# one per process: what 10^5 triangles took tells a sweep what 10^6 will
FOOTPRINTS = Footprints()
_WATCH = PeakWatch(lambda: resident_bytes())


def _batches(specs: list[RunSpec], start, frame):
    """The runs started (``start(spec)``: prepared and warmed up) in batches that close at
    BATCH_RUNS runs or BATCH_BYTES of maps, and before a run whose start, at its technique's
    :class:`Footprints` peak, would take the resident memory more than BATCH_RESIDENT over
    where the batch began (a first run starts whatever it takes); yields (the runs that could
    not start, the batch). The runs start in the order of that peak, the largest first (in
    the plan's among equals). Before the first batch, and once the consumer is done with
    each, what was freed goes back to the system; a batch whose first run is expected to pass
    through RENEW_BYTES or more starts on a GL context made anew."""
    scene = (frame.scene.key, frame.width, frame.height)
    triangles = sum(len(part.faces) for part in frame.scene.parts)
    # the runs that pass through the most first, while the group holds the least (each batch
    # leaves some of the driver's memory behind: llvmpipe keeps what its draws allocated)
    queue = sorted(specs, key=lambda spec: -FOOTPRINTS.predict(spec.technique, scene, triangles))
    _return_batch_memory()  # what the frame's set-up and the counts passed through (0.16 GiB)
    while queue:
        if FOOTPRINTS.predict(queue[0].technique, scene, triangles) >= RENEW_BYTES:
            _renew_context(frame)
        failed, batch, batch_bytes, began = [], [], 0, resident_bytes()
        while queue and len(batch) < BATCH_RUNS and batch_bytes < BATCH_BYTES:
            before = resident_bytes()
            spec = queue[0]
            if batch and (before - began + FOOTPRINTS.predict(spec.technique, scene, triangles)
                          > BATCH_RESIDENT):
                break
            queue.pop(0)
            with _WATCH.watching() as seen:
                timed = start(spec)
            FOOTPRINTS.observe(spec.technique, scene, triangles, seen.peak - before)
            if not timed.alive:
                failed.append(timed)
                continue
            batch.append(timed)
            batch_bytes += timed.output.mem_bytes
        yield failed, batch
        _return_batch_memory()


def _finish(done: list[_Timed], score):
    """The runs whose frames are done (or that failed), released and scored (``score(timed)``
    -> ``(row, arrays)``), yielded as ``(spec, row, arrays)`` within ``interrupt.finishing``:
    a Ctrl-C meanwhile waits until the consumer has stored every one of them, and is raised
    after the last."""
    if not done:
        return
    with interrupt.finishing():
        for timed in done:
            if not timed.alive:
                yield timed.spec, timed.row, None
                continue
            _release(timed)
            yield (timed.spec, *score(timed))
    interrupt.raise_if_interrupted()


def run_group(specs: list[RunSpec], frame, reference, scene_ms: float, frags_scene: int,
              renderer: str, on_frame=None):
    """Run ``specs`` (one scene and resolution, ``frame`` prepared for it) in batches of
    interleaved rounds; yields ``(spec, row, arrays)`` for each run as soon as its frames are
    done (arrays None unless it ran), before the next round: runs of one batch finish at the
    same round, a run that fails at the round it fails. Never raises for a technique's
    failure: that is the row's status. ``on_frame(specs)`` is called as each round ends,
    with the runs that rendered it (for the progress's estimate).

    On a moving scene (``frame.frames`` > 1, ``reference`` its frame 0's) each round is a
    frame of the sequence: :func:`_run_sequence`."""
    def start(spec):
        return _start(spec, frame, first_columns(spec, reference, scene_ms, frags_scene,
                                                  renderer))

    on_frame = on_frame or (lambda specs: None)
    try:  # the counts every row takes, before a batch holds memory: at 10^6 triangles the
        frame.scene.counts  # scene's edges keep 60 MiB and pass through 0.35 GiB more
    except Exception:  # scoring meets it again, as the run's own error
        pass
    if frame.frames > 1:
        yield from _run_sequence(_batches(specs, start, frame), frame, on_frame)
        return
    for failed, batch in _batches(specs, start, frame):
        yield from _finish(failed, None)
        turn, waiting = 0, list(batch)
        while waiting:
            if live := [t for t in waiting if t.alive and t.measured < t.spec.frames]:
                _measure_round(live, frame, turn)
                turn += 1
                on_frame([t.spec for t in live])
            done = [t for t in waiting if not t.alive or t.measured >= t.spec.frames]
            waiting = [t for t in waiting if t not in done]
            yield from _finish(done, lambda timed: score_run(timed, frame, reference))


def run_one(spec: RunSpec, frame, reference, scene_ms: float, frags_scene: int,
            renderer: str) -> tuple[dict, dict[str, np.ndarray] | None]:
    """Run one technique alone on a prepared frame: its row and the arrays to store with it
    (V, coverage and the technique's diagnostic maps as ``map_<name>``; None unless it ran).

    Never raises for a technique's failure: that is the row's status and error."""
    ((_, row, arrays),) = run_group([spec], frame, reference, scene_ms, frags_scene, renderer)
    return row, arrays


def _run_sequence(batches, frame, on_frame):
    """Runs on a moving scene (``frame`` at its frame 0), batch by batch: each batch goes
    through the sequence, one interleaved round per frame (each technique's frame as its cost
    policy has it, measured), and each run's frame is scored as it is rendered against that
    frame's reference (from the cache, or traced); yields ``(spec, row, arrays)`` per run, a
    failed one after the frame it failed in, the others after the last frame."""
    from ..truth.reference import compute_reference

    for failed, batch in batches:
        yield from _finish(failed, None)
        previous, traced_s, waiting = None, 0.0, list(batch)
        for t in range(frame.frames):
            if not waiting:
                break
            spec = batch[0].spec
            try:
                frame.move_to(t)
                reference = compute_reference(frame.scene, samples=spec.samples,
                                              seed=spec.ref_seed)
            except Exception as e:  # Mitsuba or GL cannot take this frame: the runs fail
                for timed in waiting:
                    timed.row.update(status="error", error=f"scene {spec.scene} frame {t}: "
                                                           f"{one_line(e)}")
                    _release(timed)
                break
            traced_s += reference.seconds
            truth = FrameTruth(t, reference, frame.compared_pixels(reference.covered))
            _measure_round(waiting, frame, t)
            for timed in waiting:
                if timed.alive:
                    _attempt(timed, observe_frame, timed, frame, truth, previous)
            on_frame([timed.spec for timed in waiting])
            previous = truth
            failed_now = [timed for timed in waiting if not timed.alive]
            waiting = [timed for timed in waiting if timed.alive]
            yield from _finish(failed_now, None)

        def score(timed):
            timed.row["ref_seconds"] = traced_s
            return sequence_score(timed, frame)

        yield from _finish(waiting, score)
        frame.move_to(0)  # the next batch warms up at frame 0
