"""A run, one module per step, in the order a run's data passes through them:

plan      experiment, scene file, command line -> validated runs (RunSpec) and scenes (Plan)
sweep     the resumable loop over a plan's pending runs, serial or through a renderer hook
progress  a long command's progress on stderr: a bar on a terminal, plain lines in a log
manifest  DIR/manifest.json: what produced DIR and how each invocation ended
measure   prepared batches, interleaved timing rounds, moving sequences
score     truth, metric, cost and timing columns, the arrays a run stores
store     arrays, then the row, into the run folder under its lock
api       ``evaluate``: one run in this process, nothing stored
estimate  what ``shadowbench plan`` says a plan's runs will take, from a folder's stored runs
tune      ``shadowbench tune``: the points' searches in rounds (tune_search: one Optuna study per
          point; tune_render: groups on a kept G-buffer and reference), the best and the
          defaults timed; tune_output: DIR/tuned.yaml and the summary

The public names are re-exported here; callers (cli, distributed, tests) use them through
this package, so that replacing one here (a test's patch) reaches every caller.
"""

from .api import Evaluation, evaluate
from .manifest import MANIFEST_FILE, SPACE_RESERVE, read_manifest, write_manifest
from .measure import run_group, run_one
from .plan import Plan, RunSpec, grid_points, parse_overrides, plan_runs, validate_params
from .score import failed_scene_row
from .store import record_run, reference_array_path
from .sweep import execute, noisy_runs, render_serial

__all__ = ["MANIFEST_FILE", "SPACE_RESERVE", "Evaluation", "Plan", "RunSpec", "evaluate",
           "execute", "failed_scene_row", "grid_points", "noisy_runs", "parse_overrides",
           "plan_runs", "read_manifest", "record_run", "reference_array_path", "render_serial",
           "run_group", "run_one", "validate_params", "write_manifest"]
