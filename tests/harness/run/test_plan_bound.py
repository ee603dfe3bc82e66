"""Planning stays bounded: max_runs has a hard limit (harness.config.limits.MAX_RUNS, 10^6),
and a plan of 10^12 combinations is counted, not made, before it is refused. Each check runs
``shadowbench run`` in a subprocess and bounds its peak resident memory (VmHWM): what planning
adds to the process once harness.run is imported, and the whole process. The imports alone
(trimesh, pyrender, scipy through harness.scene and harness.technique) peak at about 185 MB
on the development machine, so the whole is bounded at 256 MB and planning's own share at
32 MB. The address space is capped at 3 GiB so that a broken planner fails fast instead of
taking the machine's memory. Times are printed, not asserted."""

from __future__ import annotations

import json
import resource  # the address-space cap
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[3]
SCENE = {"resolution": [32, 32],
         "camera": {"position": [0, -6, 4], "target": [0, 0, 0], "yfov": 60},
         "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
         "objects": [{"shape": "plane", "size": [10, 10]},
                     {"shape": "box", "size": [1, 1, 1], "translate": [0, 0, 1.5]}]}
# six of pcf's parameters, 100 values each: 10^12 combinations
PRODUCT = {name: [i * 1e-3 for i in range(1, 101)] for name in (
    "res_factor", "min_size", "bias_min", "bias_max", "slope_bias", "normal_offset")}
# VmHWM, this process's own peak: getrusage's ru_maxrss also counts the parent's RSS at fork
MEASURE = """
import json, re, sys, time
from pathlib import Path
from harness import cli, run

def peak_mb():
    return int(re.search(r"VmHWM:\\s*(\\d+)", Path("/proc/self/status").read_text())[1]) / 1024

floor = peak_mb()
started = time.perf_counter()
code = cli.main(sys.argv[1:])
print(json.dumps({"code": code, "seconds": time.perf_counter() - started, "peak_mb": peak_mb(),
                  "planning_mb": peak_mb() - floor}))
"""
ADDRESS_SPACE = 3 << 30


def _cap_memory():
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


def _plan(tmp_path: Path, experiment: dict, *more: str) -> tuple[dict, list[str]]:
    """``shadowbench run`` of the experiment in a subprocess: its exit code, seconds in main,
    peak RSS in MB, and its stderr lines."""
    (tmp_path / "scenes.yaml").write_text(yaml.safe_dump({"scenes": {"s": SCENE}}))
    path = tmp_path / "experiment.yaml"
    path.write_text(yaml.safe_dump({"scene_file": "scenes.yaml", **experiment}))
    done = subprocess.run([sys.executable, "-c", MEASURE, "run", str(path), "--out",
                           str(tmp_path / "out"), "--quiet", *more], capture_output=True,
                          text=True, timeout=300, preexec_fn=_cap_memory, cwd=ROOT)
    lines = done.stdout.strip().splitlines()
    assert lines, done.stderr[-2000:]
    print(lines[-1])
    return json.loads(lines[-1]), done.stderr.strip().splitlines()


@pytest.mark.parametrize("max_runs, needles", [
    (None, ("plans 1,000,000,000,000 runs before duplicate points are merged, far more than "
            "the limit of 5,000 (max_runs)",
            "techniques.pcf (line", "gives all of them", "hard limit of 1,000,000")),
    (1_000_000, ("plans 1,000,000,000,000 runs before duplicate points are merged, far more "
                 "than the limit of 1,000,000",)),
])
def test_a_plan_of_10_to_the_12_runs_is_counted_and_refused(max_runs, needles, tmp_path):
    """Catches a planner that makes the runs before counting them (it took 1.5 GB in 7 s
    before it was stopped; here the 3 GiB cap ends it with a MemoryError)."""
    experiment = {"techniques": {"pcf": {"product": PRODUCT}}}
    if max_runs:
        experiment["max_runs"] = max_runs
    result, err = _plan(tmp_path, experiment)
    assert result["code"] == 2 and len(err) == 1, err
    for needle in needles:
        assert needle in err[0], err
    assert result["planning_mb"] < 32 and result["peak_mb"] < 256, result
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("where", ["experiment", "command line"])
def test_max_runs_has_a_hard_limit(where, tmp_path):
    """max_runs above 10^6 is refused, naming the key, before any planning. Catches max_runs
    without an upper bound: 10^13 admitted the 10^12 plan, which was then made (stopped by the
    3 GiB cap here)."""
    experiment = {"techniques": {"pcf": {"product": PRODUCT}}}
    if where == "experiment":
        result, err = _plan(tmp_path, {**experiment, "max_runs": 10**13})
        needle = "max_runs: must be at most 1,000,000, the hard limit"
    else:
        result, err = _plan(tmp_path, experiment, "--max-runs", str(10**13))
        needle = "--max-runs: must be at most 1,000,000, the hard limit"
    assert result["code"] == 2 and len(err) == 1, err
    assert needle in err[0] and "10,000,000,000,000" in err[0], err
    assert result["planning_mb"] < 32 and result["peak_mb"] < 256, result


def test_a_raw_count_over_the_hard_limit_is_refused_before_its_points_are_made(tmp_path):
    """2 x 10^6 grid points with max_runs at the hard limit: the raw count (before duplicates
    merge) is refused, not expanded. Catches a raw bound of 4 x max_runs alone, which made and
    validated all 2 x 10^6 points (seen failing: 1.26 GB more and 61 s before its refusal)."""
    product = {"bias_min": [i * 1e-4 for i in range(2000)],
               "bias_max": [1.0 + i * 1e-3 for i in range(1000)]}
    result, err = _plan(tmp_path, {"techniques": {"pcf": {"product": product}},
                                   "max_runs": 1_000_000})
    assert result["code"] == 2 and len(err) == 1, err
    assert "plans 2,000,000 runs before duplicate points are merged" in err[0], err
    assert "hard limit of 1,000,000 runs" in err[0], err
    assert result["planning_mb"] < 32, result
