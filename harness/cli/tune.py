"""``shadowbench tune``: the command line of :mod:`harness.run.tune` (docs/fairness.md)."""

from __future__ import annotations

import sys
import time

from ..config import ConfigError
from ..config.limits import DEFAULT_TUNE_BUDGET, DEFAULT_TUNE_SEED, MAX_TUNE_BUDGET


def add_parser(sub, planning) -> None:
    """The ``tune`` subcommand: ``run``'s options that choose runs (they choose the points to
    tune), its budget and seed."""
    q = sub.add_parser("tune", help="search each technique's tunable settings against the "
                                    "reference, per scene and point of its quality curve")
    planning(q)
    q.add_argument("--budget", type=int, default=DEFAULT_TUNE_BUDGET, metavar="N",
                   help="settings searched per scene, technique and point "
                        f"(1..{MAX_TUNE_BUDGET}; default {DEFAULT_TUNE_BUDGET})")
    q.add_argument("--seed", type=int, default=DEFAULT_TUNE_SEED, metavar="S",
                   help=f"seed of the searches (default {DEFAULT_TUNE_SEED}): the same seed asks "
                        "the same settings, so a rerun renders nothing again")
    q.add_argument("--out", required=True, help="run directory")
    q.add_argument("--quiet", action="store_true", help="no progress lines")
    q.set_defaults(func=cmd_tune)


# without an experiment, the timed runs (defaults and best) take this many frames: enough for
# a median, few enough that tuning a scene stays within minutes
TUNE_FRAMES, TUNE_WARMUP = "3", "1"


def cmd_tune(args) -> int:
    from .options import check_out, names, scene_file_or_error
    from .. import results, run
    from ..run import tune as tuning
    from ..run.tune_output import summary_lines, write_tuned

    if not 1 <= args.budget <= MAX_TUNE_BUDGET:
        raise ConfigError(f"--budget: must be in [1, {MAX_TUNE_BUDGET}], got {args.budget}")
    check_out(args.out)
    overrides = run.parse_overrides(args.set or [])
    default_frames = not args.experiment
    plan = run.plan_runs(
        experiment_path=args.experiment, scene_file=scene_file_or_error(args.scene_file),
        scenes=names("--scenes", args.scenes),
        techniques=names("--techniques", args.techniques), overrides=overrides,
        timing={"frames": args.frames or (TUNE_FRAMES if default_frames else None),
                "warmup": args.warmup or (TUNE_WARMUP if default_frames else None),
                "statistics": args.statistics, "max_runs": args.max_runs, "cost": args.cost},
        default_grids=tuning.tune_grids)
    sizes: dict[str, set] = {}
    for spec in plan.runs:
        sizes.setdefault(spec.scene, set()).add((spec.width, spec.height))
    several = sorted(name for name, s in sizes.items() if len(s) > 1)
    if several:
        raise ConfigError(f"{args.experiment}: resolutions: tune searches one image size per "
                          f"scene, and {', '.join(several)} would run at {len(sizes[several[0]])}; "
                          "list one resolution (or tune each into its own --out)")
    for name in tuning.untunable(plan):
        print(f"{name}: nothing tunable (its class declares no tunable settings); skipped",
              file=sys.stderr)
    if not any(run_spec.technique not in tuning.untunable(plan) for run_spec in plan.runs):
        print("nothing to tune", file=sys.stderr)
        return 0
    started = time.perf_counter()
    code, chosen = tuning.tune(plan, args.out, budget=args.budget, seed=args.seed,
                               fixed={t: set(p) for t, p in overrides.items()},
                               progress=not args.quiet)
    print("\n".join(summary_lines(chosen)))
    path = write_tuned(args.out, chosen, plan, budget=args.budget, seed=args.seed)
    rows = [r for r in results.read_rows(args.out) if r.get("tuning")]
    manifest = run.read_manifest(args.out)
    rendered = manifest["invocations"][-1].get("runs_rendered", 0)
    print(f"{len(rows)} tuning runs in {args.out}/results.csv ({rendered} rendered now) in "
          f"{time.perf_counter() - started:.1f} s; "
          + (f"the settings: {path}" if path else "no setting chosen"))
    for r in rows:
        if r["status"] == "error":
            print(f"  failed: {r['scene']} {r['technique']} ({r['tuning']}): {r['error']}",
                  file=sys.stderr)
    print(f"the report: shadowbench report {args.out}", file=sys.stderr)
    return code
