"""shadowbench list | plan | run | tune | reference | report | compare.

Exit codes: 0 all runs ok; 1 some runs failed (their rows say why), or the machine failed the
command (a full disk: one line naming the file); 2 bad input (one line on stderr naming file
and key, a line for each further error of a file, up to five; nothing written); 130
interrupted. Anything else is a bug: its traceback is printed
under a line asking to report it.
"""

from __future__ import annotations

import argparse
import errno
import os
import sys
import time
from pathlib import Path

from ..config import ConfigError, shipped
from ..machine import interrupt, warnings_log
from ..machine.timing import STATISTICS
# the options the commands share (tune's module imports them from there too)
from .options import (check_out as _check_out, names as _names, scene_file,
                      scene_file_or_error as _scene_file_or_error)

MAX_WORKERS = 256
# OSErrors that say the machine could not finish the command, not that the input was bad
MACHINE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.ENOMEM}


def cmd_list(args) -> int:
    """Every technique with its parameters, broken entry points and stale editable installs;
    then the scenes and the file they came from; ``--scene NAME``: that scene's objects as
    placed. Two declared baselines are bad input (exit 2), after the listing."""
    from . import listing
    from ..technique import registry

    if args.scene:
        print("\n".join(listing.inspect_lines(Path(_scene_file_or_error(args.scene_file)),
                                               args.scene)))
        return 0
    print("\n".join(listing.techniques_lines()))
    print("\n".join(listing.scenes_lines(scene_file(args.scene_file))))
    print("\n".join(listing.experiments_lines()))
    for line in registry.stale_installs():
        print(f"warning: {line}", file=sys.stderr)
    registry.baseline()
    return 0


def _plan(args):
    from .. import run

    experiment = str(shipped.experiment_file(args.experiment)) if args.experiment else None
    return run.plan_runs(
        experiment_path=experiment, scene_file=_scene_file_or_error(args.scene_file),
        scenes=_names("--scenes", args.scenes),
        techniques=_names("--techniques", args.techniques),
        overrides=run.parse_overrides(args.set or []),
        timing={"frames": args.frames, "warmup": args.warmup, "statistics": args.statistics,
                "max_runs": args.max_runs, "cost": args.cost})


def cmd_plan(args) -> int:
    """The runs ``run`` would make with these arguments, rendering nothing."""
    from . import listing

    plan = _plan(args)
    out = Path(args.out) if args.out else None
    stored = Path(args.from_dir) if args.from_dir else out
    print("\n".join(listing.plan_lines(plan, out, stored)))
    return 0


def cmd_run(args) -> int:
    from .. import run
    from ..run.progress import verbosity
    from . import summary

    if args.scheduler and args.executor != "dask":
        raise ConfigError("--scheduler goes with --executor dask")
    if not 1 <= args.workers <= MAX_WORKERS:
        raise ConfigError(f"--workers: must be in [1, {MAX_WORKERS}], got {args.workers}")
    _check_out(args.out)
    plan = _plan(args)
    for note in plan.notes:
        print(note, file=sys.stderr)
    interrupt.raise_if_interrupted()
    started = time.perf_counter()
    mode = verbosity(args.quiet, args.verbose)
    if args.executor == "dask":
        from ..run.distributed import dask_renderer

        # the cluster is up (or the scheduler answered) before anything is written to --out
        with dask_renderer(scheduler=args.scheduler, n_workers=args.workers,
                           platform_name=args.platform) as renderer:
            code = run.execute(plan, args.out, platform_name=args.platform, progress=mode,
                               renderer=renderer, retime_noisy=args.retime_noisy)
    else:
        code = run.execute(plan, args.out, platform_name=args.platform, progress=mode,
                           retime_noisy=args.retime_noisy)
    summary.print_run(plan, Path(args.out), time.perf_counter() - started)
    if args.report:
        from ..report import build_report

        print(f"report: {build_report(args.out, progress=mode).resolve()}", flush=True)
    else:
        print(f"the report: shadowbench report {args.out}", flush=True)
    return code


def cmd_reference(args) -> int:
    import numpy as np
    from pydantic import ValidationError

    from ..config import ReferenceSettings, check_resolution
    from ..truth.reference import compute_reference
    from ..report import visibility_png
    from ..results import inside, save_arrays
    from ..run.progress import Progress, verbosity
    from ..run.store import exclusive, reference_array_path
    from ..scene import load_scene

    # the bounds of an experiment's reference samples and of a scene's resolution
    try:
        ReferenceSettings(samples=args.samples)
    except ValidationError as e:
        message = e.errors()[0]["msg"].removeprefix("Value error, ")
        raise ConfigError(f"--samples: {message}") from None
    if args.resolution:
        try:
            check_resolution(args.resolution)
        except ValueError as e:
            raise ConfigError(f"--resolution: {e}") from None
    _check_out(args.out)
    scene = load_scene(args.scene, _scene_file_or_error(args.scene_file))
    if args.resolution:
        scene = scene.with_resolution(*args.resolution)
    interrupt.raise_if_interrupted()
    progress = Progress(1, unit="reference", mode=verbosity(args.quiet, args.verbose))
    progress.stage(f"{scene.name} {scene.width}x{scene.height}: {args.samples} samples")
    progress.status("tracing")
    try:
        ref = compute_reference(scene, samples=args.samples, use_cache=not args.no_cache)
        progress.step(f"{scene.name}: {'cached' if ref.cached else f'{ref.seconds:.2f} s'}")
    finally:
        progress.close()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with exclusive(out):
        path = inside(out, reference_array_path(scene.name, scene.width, scene.height,
                                                args.samples, 0))
        extra = {"direct": ref.direct} if ref.direct is not None else {}
        save_arrays(path, visibility=ref.visibility, covered=ref.covered, **extra)
        visibility_png(ref.visibility, ref.covered, path.with_suffix(".png"))
    print(f"{path} ({scene.width}x{scene.height}, {args.samples} samples, {ref.variant}, "
          f"{'cached' if ref.cached else f'{ref.seconds:.2f} s'}; covered "
          f"{np.mean(ref.covered):.1%}, lit {np.mean(ref.visibility[ref.covered]):.1%})")
    return 0


def cmd_report(args) -> int:
    from ..report import build_report
    from ..run.progress import verbosity

    print(build_report(args.dir, progress=verbosity(args.quiet, args.verbose)).resolve())
    return 0


def cmd_compare(args) -> int:
    from ..report import compare

    result = compare.compare(args.before, args.after, factor=args.factor,
                             tolerance=args.tolerance)
    print(compare.text(result, only_changed=args.only_changed))
    if args.html:
        try:
            page = compare.write_html(result, args.html)
        except OSError as e:  # named as the user wrote it
            raise OSError(e.errno, e.strerror, f"--html {args.html}") from None
        print(f"page: {page.resolve()}", file=sys.stderr)
    return 1 if result.worse else 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="shadowbench", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)

    def output_options(q):
        """How a long command shows its progress on stderr (its result goes to stdout)."""
        shown = q.add_mutually_exclusive_group()
        shown.add_argument("--quiet", action="store_true",
                           help="no progress: errors and the summary only")
        shown.add_argument("--verbose", action="store_true", help="a line for each run")

    def scene_file_option(q):
        q.add_argument("--scene-file", default=None,
                       help="scene file (default ./scenes.yaml, else the shipped scenes)")

    q = sub.add_parser("list", help="techniques with their parameters; scenes")
    scene_file_option(q)
    q.add_argument("--scene", metavar="NAME",
                   help="that scene's objects as placed: bounds, up axis, triangles, parts")
    q.set_defaults(func=cmd_list)

    def planning(q):
        """The options that choose the runs: ``run``'s and ``plan``'s."""
        q.add_argument("experiment", nargs="?",
                       help="experiment YAML: a path, or a shipped one by name (default, "
                            "hard_cases, papers/sv: `shadowbench list` names them)")
        scene_file_option(q)
        q.add_argument("--scenes", help="comma-separated scene names")
        q.add_argument("--techniques", help="comma-separated technique names")
        q.add_argument("--set", action="append", metavar="TECHNIQUE.PARAM=VALUE",
                       help="override a parameter, e.g. --set pcf.k=16 (repeatable)")
        q.add_argument("--frames", metavar="N",
                       help="measured frames per run, after the warm-up (default: the "
                            "experiment's, else 15)")
        q.add_argument("--warmup", metavar="N",
                       help="unmeasured frames before them (default: the experiment's, else 2)")
        q.add_argument("--statistics", metavar="METHOD",
                       help=f"the 95%% interval of each median time: {' or '.join(STATISTICS)} "
                            "(default: the experiment's, else order)")
        q.add_argument("--max-runs", metavar="N",
                       help="refuse a plan of more runs (default: the experiment's, else 5000; at "
                            "most 1000000)")
        q.add_argument("--cost", metavar="POLICY",
                       help="dynamic (every frame pays for what depends on the light and the "
                            "geometry) or static (that is done once, reported as setup_ms; "
                            "default: the experiment's, else dynamic)")

    q = sub.add_parser("plan", help="the runs `run` would make, grouped, with a time estimate; "
                                    "renders nothing")
    planning(q)
    q.add_argument("--out", help="the folder `run` would write: its runs are done already")
    q.add_argument("--from", dest="from_dir", metavar="DIR",
                   help="estimate the time from the runs stored in DIR (default: --out)")
    q.set_defaults(func=cmd_plan)

    q = sub.add_parser("run", help="run an experiment (or every technique on every scene)")
    planning(q)
    q.add_argument("--out", required=True, help="run directory")
    q.add_argument("--platform", choices=["osmesa", "egl"], default=None,
                   help="GL platform (default osmesa, or $SHADOWBENCH_GL)")
    q.add_argument("--executor", choices=["serial", "dask"], default="serial",
                   help="serial (this process) or dask (a Dask cluster; the client writes)")
    q.add_argument("--scheduler", metavar="ADDRESS",
                   help="with --executor dask: an existing scheduler (default: a LocalCluster)")
    q.add_argument("--workers", type=int, default=2, metavar="N",
                   help="with --executor dask and no --scheduler: LocalCluster workers "
                        "(one thread each; default 2)")
    q.add_argument("--retime-noisy", action="store_true",
                   help="then measure again the runs timed while the machine was busy")
    output_options(q)
    q.add_argument("--report", action="store_true", help="build DIR/index.html at the end")
    q.set_defaults(func=cmd_run)

    from .tune import add_parser as add_tune_parser

    add_tune_parser(sub, planning)

    q = sub.add_parser("reference", help="compute (or fetch from cache) a scene's reference")
    q.add_argument("--scene", required=True)
    scene_file_option(q)
    q.add_argument("--out", required=True)
    q.add_argument("--samples", type=int, default=16, help="samples per pixel (a square)")
    q.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"))
    q.add_argument("--no-cache", action="store_true")
    output_options(q)
    q.set_defaults(func=cmd_reference)

    q = sub.add_parser("report", help="build DIR/index.html from stored results")
    q.add_argument("dir")
    output_options(q)
    q.set_defaults(func=cmd_report)

    q = sub.add_parser("compare", help="what changed from results folder BEFORE to AFTER, run by "
                                       "run (a run in one folder only paired with the other's "
                                       "of its scene, size and technique, its changed "
                                       "parameters shown); exit 1 when something got worse")
    q.add_argument("before")
    q.add_argument("after")
    q.add_argument("--factor", type=float, default=1.1,
                   help="time is worse beyond this ratio, with each median outside the other "
                        "run's interval and neither run noisy (else undecided; default 1.1)")
    q.add_argument("--tolerance", type=float, default=0.05,
                   help="an error metric is worse when it grew by more than this fraction "
                        "(default 0.05)")
    q.add_argument("--only-changed", action="store_true", help="list only runs that changed")
    q.add_argument("--html", metavar="FILE", help="also write the comparison as a page")
    q.set_defaults(func=cmd_compare)
    return p


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit code. Run as the program (``argv`` None), an
    interrupted command ends the process at once: the interpreter's own teardown with GL and
    LLVM loaded takes a second or more, and everything on disk is consistent already."""
    with interrupt.stop_on_signals():
        try:
            args = build_parser().parse_args(argv)
            if getattr(args, "platform", None):
                os.environ["SHADOWBENCH_GL"] = os.environ["PYOPENGL_PLATFORM"] = args.platform
            with warnings_log.Caught() as caught:
                code = args.func(args)
            _log_warnings(args, caught.lines)
            return code
        except KeyboardInterrupt:
            interrupt.announce()
            if argv is None:
                sys.stdout.flush()
                os._exit(interrupt.EXIT_CODE)
            return interrupt.EXIT_CODE
        except Exception as e:
            known = _known_failure(e)
            if known is None:
                import traceback

                print("shadowbench: internal error (a bug): please report it with the command "
                      "and this traceback", file=sys.stderr)
                traceback.print_exc()
                return 1
            code, message = known
            for line in (message, *getattr(e, "more", ())):  # a file's further errors
                print(f"shadowbench: {_printable(line)}", file=sys.stderr)
            return code


def _log_warnings(args, lines: list[str]) -> None:
    """Libraries' warnings (trimesh, scikit-image, NumPy, Mitsuba) go to DIR/warnings.log of
    the command's folder, never onto the terminal among the progress lines and the result; a
    warning about one run's numbers is in that run's ``warnings`` column already. Without a
    folder (compare, list) they are dropped; a bad input (exit 2) logs nothing."""
    folder = getattr(args, "out", None) or getattr(args, "dir", None)
    warnings_log.append(folder, lines)


def _known_failure(e: Exception) -> tuple[int, str] | None:
    """(exit code, one-line message) for an expected failure; None for a bug."""
    from ..gl.context import BackendError
    from ..truth.reference import UntraceableSceneError

    if isinstance(e, (ConfigError, BackendError)):  # a RegistryError is a ConfigError
        return 2, str(e)
    if isinstance(e, UntraceableSceneError):  # `reference` on a scene Mitsuba cannot trace
        return 1, str(e)
    if isinstance(e, OSError):
        where = ": ".join(str(f) for f in (e.filename, e.filename2) if f is not None)
        reason = e.strerror or str(e)
        return (1 if e.errno in MACHINE_ERRNOS else 2), f"{where}: {reason}" if where else reason
    if isinstance(e, MemoryError):
        return 1, "out of memory; choose smaller resolutions, maps or fewer samples"
    return None


def _printable(message: str) -> str:
    """One line: newlines and other control characters (from names in files) escaped."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)

