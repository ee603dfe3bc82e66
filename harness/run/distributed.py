"""Distributed sweeps on Dask: workers render and score runs; the client alone writes.

Each worker process owns its GL context, its frames and its reference cache. A task is a
piece of one scene and resolution (at most ``TASK_RUNS`` runs), which the worker measures in
interleaved rounds exactly as the serial runner does (:func:`harness.run.run_group`); it
returns the runs' rows and arrays, and the client records them as the serial runner does
(same ids, same files, atomic results.csv), so a sweep killed at the client or at a worker
resumes the same way: runs already in results.csv are not sent again (a task killed midway
is rendered again whole).

Timing runs must not share a worker: a LocalCluster gets one thread per worker; an external
cluster's workers must run one thread each (``dask worker --nthreads 1``) or declare the
resource ``gl=1`` (``dask worker --resources gl=1``), which the tasks then ask for.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path

from ..config import ConfigError
from ..machine import warnings_log
from ..machine.interrupt import deferred, finishing, raise_if_interrupted
from . import Plan, RunSpec, record_run
from .measure import return_freed_memory

# Runs per task: interleaving needs several runs in one worker, spreading the sweep needs
# several tasks per worker.
TASK_RUNS = 8

_worker_frames: dict = {}


def _frame_on_worker(scene, frames: int, warmup: int):
    """This worker's frame for the scene (one kept at a time) and its no-shadow cost."""
    from ..technique import Frame

    key = (scene.key, scene.width, scene.height)
    if key not in _worker_frames:
        for frame, _, _ in _worker_frames.values():
            frame.release()
        _worker_frames.clear()
        return_freed_memory()
        frame = Frame(scene)
        try:
            scene_ms, frags_scene = frame.measure_scene_pass(frames, warmup)
        except BaseException:
            frame.release()
            raise
        _worker_frames[key] = (frame, scene_ms, frags_scene)
    return _worker_frames[key]


def run_on_worker(specs: list[RunSpec], scene, platform: str | None):
    """Runs of one scene and resolution on this worker, in interleaved rounds:
    ([(row, its arrays or None), ...] in the order of ``specs``, the reference or None, the
    lines libraries warned meanwhile). A scene whose reference or frame fails gives its runs
    error rows, as in the serial runner. The warnings go back to the client, which keeps them
    in the folder's warnings.log as it does its own: a worker's stderr is the terminal."""
    with warnings_log.Caught() as caught:  # one task at a time: a worker has one thread
        finished, reference = _runs_on_worker(specs, scene, platform)
    return finished, reference, caught.lines


def _runs_on_worker(specs: list[RunSpec], scene, platform: str | None):
    from distributed import get_worker

    from ..gl.context import get_context
    from ..truth.reference import compute_reference
    from . import failed_scene_row, run_group

    first = specs[0]
    context = get_context(platform)
    try:
        reference = compute_reference(scene.at_frame(0), samples=first.samples, seed=first.ref_seed)
        frame, scene_ms, frags_scene = _frame_on_worker(scene, first.frames, first.warmup)
    except Exception as e:  # Mitsuba or GL cannot take this scene: its runs fail
        finished = [(failed_scene_row(spec, e), None) for spec in specs]
        reference = None
    else:
        done = {}
        for spec, row, arrays in run_group(specs, frame, reference, scene_ms, frags_scene,
                                           context.renderer):
            done[spec.run_id] = (row, arrays)
        finished = [done[spec.run_id] for spec in specs]
    for row, _ in finished:
        row["worker"] = get_worker().address
    return finished, reference


def tasks_of(pending: list[RunSpec]) -> list[list[RunSpec]]:
    """The pending runs cut into tasks: each group of one scene and resolution (and reference
    settings) in near-equal pieces of at most TASK_RUNS runs."""
    groups: dict[tuple, list[RunSpec]] = {}
    for spec in pending:
        groups.setdefault((spec.scene, spec.width, spec.height, spec.samples, spec.ref_seed),
                          []).append(spec)
    tasks = []
    for specs in groups.values():
        pieces = -(-len(specs) // TASK_RUNS)
        tasks.extend(specs[i::pieces] for i in range(pieces))
    return tasks


def _task_options(client) -> dict:
    workers = client.scheduler_info()["workers"].values()
    if not workers:
        raise ConfigError("the Dask cluster has no workers")
    if all(w.get("resources", {}).get("gl") for w in workers):
        return {"resources": {"gl": 1}}
    crowded = [w["id"] for w in workers if w.get("nthreads", 1) > 1]
    if crowded:
        raise ConfigError(
            f"Dask workers {', '.join(map(str, crowded))} run more than one thread, so timing "
            "runs would share them; start workers with --nthreads 1 or --resources gl=1")
    return {}


SCHEDULER_TIMEOUT_S = 5


@contextmanager
def dask_renderer(*, scheduler: str | None = None, n_workers: int = 2,
                  platform_name: str | None = None):
    """Within the block, a renderer for :func:`harness.run.execute` that sends each run to a
    Dask cluster: the one at ``scheduler``, or a new LocalCluster of ``n_workers`` one-thread
    workers. The cluster is reached (or started) on entry, before the sweep writes anything,
    and a scheduler that does not answer within ``SCHEDULER_TIMEOUT_S`` is a ConfigError."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise ConfigError("--executor dask needs Dask: pip install 'hard-shadow-bench[dask]'") from None

    cluster = client = None
    try:
        if scheduler is None:
            env = {k: os.environ[k] for k in ("SHADOWBENCH_GL", "PYOPENGL_PLATFORM",
                                              "SHADOWBENCH_CACHE") if k in os.environ}
            with deferred():  # interrupted halfway, a cluster fails in its exit handler
                # a free port: parallel clusters would each warn that the default one is taken
                cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1,
                                       processes=True, dashboard_address=":0", env=env)
                client = Client(cluster)
        else:
            try:
                client = Client(scheduler, timeout=SCHEDULER_TIMEOUT_S)
            except Exception as e:  # refused, timed out, a malformed address, ...
                reason = " ".join(f"{type(e).__name__}: {e}".split())[:200]
                raise ConfigError(f"--scheduler {scheduler}: no Dask scheduler answers there "
                                  f"({reason})") from None
        options = _task_options(client)

        def render(plan: Plan, pending: list[RunSpec], out_dir: Path, context, bar):
            tasks = tasks_of(pending)
            futures = [client.submit(run_on_worker, specs,
                                     plan.scenes[specs[0].scene].with_resolution(
                                         specs[0].width, specs[0].height),
                                     platform_name, key=f"runs-{specs[0].run_id}", pure=False,
                                     **options)
                       for specs in tasks]
            specs_of = {f.key: specs for f, specs in zip(futures, tasks)}
            bar.stage(f"{len(tasks)} tasks on {len(client.scheduler_info()['workers'])} "
                      "Dask workers")
            for future in as_completed(futures):
                finished, reference, warned = future.result()
                warnings_log.append(out_dir, warned)
                with finishing():  # a task's runs are all done: each stored even on Ctrl-C
                    for spec, (row, arrays) in zip(specs_of[future.key], finished):
                        record_run(out_dir, spec, row, arrays, reference)
                        yield spec, row
                raise_if_interrupted()

        yield render
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
