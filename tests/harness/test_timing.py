"""Timing statistics (median interval), interleaved rounds, machine load and their command line."""

import json
import math
import subprocess
import sys
import time

import numpy as np
import pytest
from helpers import rows_by_run_id
from scipy import stats

from harness import cli
from harness.technique import registry
from harness.machine import timing
from harness.run import score as runner
from harness.technique import Technique, TechniqueParams


@pytest.mark.parametrize("n", [6, 7, 10, 15, 23, 30, 59, 100])
def test_order_statistic_ranks_are_the_narrowest_with_95_percent_coverage(n):
    """Coverage from scipy's binomial, independently of the running sum in the module.

    Catches: the rank one too wide or too narrow (an off-by-one in the binomial sum), e.g.
    ``below`` summed before the comparison uses P(B <= rank) instead of P(B <= rank - 1)."""
    low, high = timing.order_statistic_ranks(n)
    assert high == n + 1 - low

    def coverage(rank):
        return 1 - 2 * stats.binom.cdf(rank - 1, n, 0.5)

    assert coverage(low) >= 0.95
    assert coverage(low + 1) < 0.95
    if n == 100:
        assert (low, high) == (40, 61)  # the textbook ranks for n = 100


def test_below_six_samples_the_interval_is_the_range():
    """Catches: an interval narrower than [min, max] for n < 6 (no interval reaches 95%)."""
    x = [3.0, 1.0, 2.0, 5.0, 4.0]
    assert timing.median_interval(x) == (3.0, 1.0, 5.0)
    assert timing.median_interval([2.5]) == (2.5, 2.5, 2.5)


@pytest.mark.parametrize("method", timing.STATISTICS)
def test_interval_contains_the_median_and_narrows_as_frames_grow(method):
    """Synthetic frame times (log-normal, skewed like frame times); pure function.

    Catches: an interval of the samples' spread (min/max, or mean +- 2 sd), which does not
    narrow with more samples; or one that leaves out the median."""
    rng = np.random.default_rng(1)
    widths = []
    for n in (15, 60, 240, 960):
        x = rng.lognormal(mean=2.0, sigma=0.3, size=n)
        median, low, high = timing.median_interval(x, method=method)
        assert median == np.median(x)
        assert low <= median <= high
        assert low >= x.min() and high <= x.max()
        widths.append(high - low)
    assert all(a > b for a, b in zip(widths, widths[1:])), widths
    # the width of a median's interval falls as 1 / sqrt(n): 64x the samples, about 1/8 the width
    assert widths[-1] < widths[0] / 4, widths


def test_order_interval_covers_the_true_median_95_percent_of_the_time():
    """4000 synthetic runs of 15 exponential frame times; the true median is ln 2. The exact
    coverage of ranks (4, 12) is 1 - 2 P(B <= 3) = 0.9648.

    Catches: ranks (5, 11) (coverage 0.88) or a percentile interval of the samples."""
    rng = np.random.default_rng(2)
    hits = 0
    for _ in range(4000):
        _, low, high = timing.median_interval(rng.exponential(size=15))
        hits += low <= math.log(2) <= high
    assert 0.95 <= hits / 4000 <= 0.98, hits / 4000


def test_bootstrap_is_seeded():
    """Catches: an unseeded generator (a rerun gives other intervals)."""
    x = np.random.default_rng(3).lognormal(size=15)
    assert timing.median_interval(x, method="bootstrap") == \
        timing.median_interval(x, method="bootstrap")
    with pytest.raises(ValueError, match="method must be one of"):
        timing.median_interval(x, method="mean")


def test_a_real_run_stores_the_interval_of_its_frames(scene_at, evaluate):
    """Once on a real run: the stored interval is the order-statistic interval of the stored
    frame times (ranks 4 and 12 of 15) and contains the median; each pass likewise.

    Catches: the interval taken over the passes' medians or over the warm-up frames, and a
    row whose time_ms is not the median of its frames."""
    row = evaluate(scene_at("box_plane", 64), "sm", {"res": 256}, frames=15, warmup=2).row
    frames = sorted(row["frame_ms"])
    assert len(frames) == 15
    assert row["time_ms_ci_low"] <= row["time_ms"] <= row["time_ms_ci_high"]
    assert row["time_ms"] == pytest.approx(frames[7], abs=1e-4)
    assert row["time_ms_ci_low"] == pytest.approx(frames[3], abs=1e-4)
    assert row["time_ms_ci_high"] == pytest.approx(frames[11], abs=1e-4)
    assert [p["name"] for p in row["passes"]] == ["light_fit", "shadow_map", "shading"]
    for p in row["passes"]:
        assert p["ms_ci_low"] <= p["ms"] <= p["ms_ci_high"]


# --- interleaved rounds ----------------------------------------------------------------------

class Logged(Technique):
    """Records each call, so a test sees the order in which runs render.

    ======  ==============================  =======  =====
    Name    Meaning                         Default  Range
    ======  ==============================  =======  =====
    ``id``  which run                       0        any
    ``mb``  map bytes it reports, in MiB    1        >= 0
    ======  ==============================  =======  =====
    """

    name = "logged"
    summary = "logs its calls"
    paper = "none"
    calls: list = []
    live: set = set()
    most_live = 0

    class Params(TechniqueParams):
        id: int = 0
        mb: int = 1
        passes_mb: int = 0  # held for 50 ms in prepare (Logged.passing), then let go

    passing = 0

    def prepare(self, frame):
        Logged.live.add(self.params.id)
        Logged.most_live = max(Logged.most_live, len(Logged.live))
        if self.params.passes_mb:
            Logged.passing = self.params.passes_mb * 2**20
            time.sleep(0.05)
            Logged.passing = 0

    def render(self, frame):
        Logged.calls.append((self.params.id, frame.meter.measuring))
        with frame.measure("clear"):
            frame.begin_visibility()
        return frame.output(mem_bytes=self.params.mb * 2**20, fetches_per_px=0)

    def release(self):
        Logged.live.discard(self.params.id)


@pytest.fixture
def logged(monkeypatch, gl_context):
    from harness.run import measure

    found = dict(registry.techniques())
    found["logged"] = Logged
    monkeypatch.setattr(registry, "techniques", lambda: found)
    monkeypatch.setattr(measure, "FOOTPRINTS", measure.Footprints())  # no other test's
    Logged.calls, Logged.live, Logged.most_live = [], set(), 0
    Logged.passing = 0
    return Logged


def _sweep(tmp_path, ids, mb=1, frames=4, warmup=1):
    experiment = tmp_path / "logged.yaml"
    experiment.write_text(json.dumps({
        "scenes": ["box_plane"], "resolutions": [[32, 32]], "frames": frames, "warmup": warmup,
        "reference": {"samples": 1},
        "techniques": {"logged": {"product": {"id": list(ids)}, "set": {"mb": mb}}}}))
    return experiment


def test_runs_are_measured_in_interleaved_rounds(logged, tmp_path, small_scene_file):
    """Between two measured frames of a run, every other run of the group renders one, and
    the round's first run turns.

    Catches: runs measured one after another (all frames of run 0, then run 1, ...), and
    rounds always in the same order."""
    scene_file = small_scene_file("box_plane", size=(32, 32))
    code = cli.main(["run", str(_sweep(tmp_path, range(3))), "--scene-file", str(scene_file),
                     "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 0
    warm = [i for i, measuring in logged.calls if not measuring]
    measured = [i for i, measuring in logged.calls if measuring]
    assert warm == [0, 1, 2]  # each prepared and warmed up, then the rounds
    rounds = [measured[k:k + 3] for k in range(0, len(measured), 3)]
    assert rounds == [[0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 1, 2]]
    assert logged.most_live == 3


def test_batches_keep_prepared_maps_within_the_budget(logged, tmp_path, small_scene_file):
    """Runs reporting 100 MiB of maps each: a batch closes at 256 MiB (three runs), so no
    more than three are prepared at once, and every run still gets all its frames.

    Catches: every run of the group prepared at once (7 live), whatever its memory."""
    scene_file = small_scene_file("box_plane", size=(32, 32))
    code = cli.main(["run", str(_sweep(tmp_path, range(7), mb=100)), "--scene-file",
                     str(scene_file), "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 0
    assert logged.most_live == 3
    measured = [i for i, measuring in logged.calls if measuring]
    assert sorted(measured) == sorted(list(range(7)) * 4)


def test_batches_close_when_resident_memory_grows_by_the_budget(logged, tmp_path,
                                                                small_scene_file, monkeypatch):
    """Runs of 1 MiB of maps that each hold 0.7 GiB of other buffers (the process's resident
    memory as the live runs make it): a batch takes no run that would take it more than 1.5
    GiB over where it began (two runs), and every run still gets all its frames. Catches
    batches that count only the maps (7 live: 4.9 GiB) and a budget on the total, which a
    process that stays large after a batch (here 4 GiB) would hold to one run a batch."""
    from harness.run import measure

    monkeypatch.setattr(measure, "resident_bytes",
                        lambda: int((4 + 0.7 * len(logged.live)) * 2**30))
    scene_file = small_scene_file("box_plane", size=(32, 32))
    code = cli.main(["run", str(_sweep(tmp_path, range(7))), "--scene-file", str(scene_file),
                     "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 0
    assert logged.most_live == 2
    measured = [i for i, measuring in logged.calls if measuring]
    assert sorted(measured) == sorted(list(range(7)) * 4)


def test_batches_leave_room_for_what_a_start_passes_through(logged, tmp_path, small_scene_file,
                                                           monkeypatch):
    """Runs that each keep 0.4 GiB and pass through 0.6 GiB more while they prepare (sv's
    prepare at 10^6 triangles: 2.1 GiB through, 0.6 kept): the second run's start peaks 1.4
    GiB over the batch's beginning, a third's would peak at 1.8, over the 1.5 GiB budget, so
    a batch holds two; the peak a run showed is what the next run of its technique is
    expected to take. Catches a budget on what the runs keep alone (four a batch, peaking at
    2.2 GiB) and the batches of before issue 53 (five, at 2.6)."""
    from harness.run import measure

    monkeypatch.setattr(measure, "resident_bytes", lambda: int(
        (4 + 0.4 * len(logged.live)) * 2**30 + logged.passing))
    experiment = _sweep(tmp_path, range(7))
    spec = json.loads(experiment.read_text())
    spec["techniques"]["logged"]["set"]["passes_mb"] = 614  # 0.6 GiB
    experiment.write_text(json.dumps(spec))
    scene_file = small_scene_file("box_plane", size=(32, 32))
    code = cli.main(["run", str(experiment), "--scene-file", str(scene_file),
                     "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 0
    assert logged.most_live == 2
    measured = [i for i, measuring in logged.calls if measuring]
    assert sorted(measured) == sorted(list(range(7)) * 4)


def test_footprints_grow_with_the_triangles_from_smaller_scenes():
    """A technique's start on a scene it ran on: the most it took there; on another: the most
    of what scenes of as many triangles took and of the line through its two largest smaller
    scenes (a map's bytes stay, an edge buffer's grow), or from the one, as a technique never
    seen for the triangles more; never seen: UNSEEN_BYTES_PER_TRIANGLE a triangle."""
    from harness.run.measure import UNSEEN_BYTES_PER_TRIANGLE, Footprints

    f = Footprints()
    assert f.predict("sv", ("a", 512, 512), 10**6) == UNSEEN_BYTES_PER_TRIANGLE * 10**6
    f.observe("sv", ("t4", 512, 512), 10**4, 30 * 2**20)
    # from one size: what it took there, and as an unseen technique for the triangles more
    assert f.predict("sv", ("t5", 512, 512), 10**5) == 30 * 2**20 + UNSEEN_BYTES_PER_TRIANGLE * 90_000
    f.observe("sv", ("t5", 512, 512), 10**5, 210 * 2**20)
    f.observe("sv", ("t5", 512, 512), 10**5, 200 * 2**20)  # another setting: the most stays
    assert f.predict("sv", ("t5", 512, 512), 10**5) == 210 * 2**20
    assert f.predict("sv", ("t6", 512, 512), 10**6) == 210 * 2**20 + 2 * 900 * 2**20
    f.observe("sm", ("t4", 512, 512), 10**4, 167 * 2**20)
    f.observe("sm", ("t5", 512, 512), 10**5, 167 * 2**20)
    assert f.predict("sm", ("t6", 512, 512), 10**6) == 167 * 2**20  # a map's bytes stay
    assert f.predict("sm", ("t3", 512, 512), 10**3) == UNSEEN_BYTES_PER_TRIANGLE * 10**3
    # another family at the same size took less than the smaller scenes promise: the most
    f.observe("sv", ("other6", 512, 512), 10**6, 1400 * 2**20)
    assert f.predict("sv", ("t6", 512, 512), 10**6) == 2010 * 2**20
    f.observe("sv", ("big6", 512, 512), 10**6, 2500 * 2**20)
    assert f.predict("sv", ("t6", 512, 512), 10**6) == 2500 * 2**20


# --- machine load ----------------------------------------------------------------------------

BUSY_LOOP = "import time\nend = time.time() + 120\nwhile time.time() < end:\n    pass\n"


@pytest.fixture
def busy_loops():
    """``busy_loops(n)``: n processes spinning on a CPU until the test ends; returns their
    psutil handles."""
    import psutil

    started = []

    def start(n):
        started.extend(subprocess.Popen([sys.executable, "-c", BUSY_LOOP]) for _ in range(n))
        time.sleep(0.3)
        return [psutil.Process(p.pid) for p in started]

    yield start
    for p in started:
        p.kill()
        p.wait()


def _cpu_seconds(processes) -> float:
    return sum(sum(p.cpu_times()[:2]) for p in processes)


def test_cpu_contention_rises_with_a_busy_process_beside_the_run(scene_at, evaluate, busy_loops):
    """Busy loops in other processes take a share of the machine's CPU that psutil measures
    from their own counters; the run's cpu_contention includes at least most of that share
    (other processes' load can only add to it), and the run is flagged noisy. (On a shared
    machine the loops may get little CPU; two per core get a measurable share.)

    Catches: no load attributed to the run's rounds (contention 0 or empty), or attributed to
    only part of them."""
    import os

    scene = scene_at("box_plane", 256)
    quiet = evaluate(scene, "pcf", {"k": 16}, frames=20, warmup=1).row["cpu_contention"]
    loops = busy_loops(2 * os.cpu_count())
    before, start = _cpu_seconds(loops), time.perf_counter()
    row = evaluate(scene, "pcf", {"k": 16}, frames=20, warmup=1).row
    share = (_cpu_seconds(loops) - before) / ((time.perf_counter() - start) * os.cpu_count())
    print(f"cpu_contention {quiet:.2f} alone, {row['cpu_contention']:.2f} beside busy loops "
          f"whose share was {share:.2f}")
    assert share > 0.05
    assert row["cpu_contention"] >= 0.7 * share
    assert row["noisy"] == int(row["cpu_contention"] > timing.NOISY_CONTENTION) == 1


def test_load_of_a_window_matches_psutil(scene_at, evaluate, busy_loops):
    """Over a window in which this process renders (llvmpipe's threads busy) beside a busy
    loop, the sampler's own time and other processes' time equal psutil's independent
    readings: the process's time over all its threads, and the machine's busy time (user,
    nice, system, irq, softirq, steal) less it.

    Catches: getrusage(RUSAGE_THREAD) (llvmpipe's threads counted as other processes), and own
    time not subtracted from the machine's busy time."""
    import psutil

    loops = busy_loops(1)
    process = psutil.Process()

    def machine_busy():
        t = psutil.cpu_times()
        return t.user + t.nice + t.system + t.irq + t.softirq + t.steal

    before, ps_busy, ps_own, loop = (timing.cpu_sample(), machine_busy(),
                                     sum(process.cpu_times()[:2]), _cpu_seconds(loops))
    evaluate(scene_at("sphere_plane", 512), "pcf", {"k": 16, "res": 2048}, frames=6)
    after = timing.cpu_sample()
    ps_own = sum(process.cpu_times()[:2]) - ps_own
    ps_others = machine_busy() - ps_busy - ps_own
    loop = _cpu_seconds(loops) - loop
    others, _ = timing.others_time(before, after)
    assert process.num_threads() > 1  # the renderer's threads
    assert after.own - before.own == pytest.approx(ps_own, abs=0.05 + 0.05 * ps_own)
    assert others == pytest.approx(ps_others, abs=0.05 + 0.05 * ps_others)
    assert others >= 0.9 * loop - 0.05  # the loop is another process


def test_contention_arithmetic():
    """Catches: a share over the process's own time instead of the machine's, or negative
    shares from tick rounding left unclipped."""
    a = timing.CpuSample(busy=10.0, total=40.0, own=2.0)
    b = timing.CpuSample(busy=16.0, total=48.0, own=5.0)
    assert timing.others_time(a, b) == (3.0, 8.0)
    assert timing.contention(3.0, 8.0) == 0.375
    assert timing.contention(-0.01, 8.0) == 0.0
    assert timing.contention(1.0, 0.0) is None


# --- the command line ------------------------------------------------------------------------

@pytest.mark.parametrize(("args", "message"), [
    (["--frames", "0"], "--frames: Input should be greater than or equal to 1, got '0'"),
    (["--warmup", "-1"], "--warmup: Input should be greater than or equal to 0, got '-1'"),
    (["--statistics", "mean"], "--statistics: Input should be 'order' or 'bootstrap'"),
])
def test_bad_timing_options_exit_2_with_one_line(args, message, tmp_path, capsys):
    """Catches: options passed through unchecked (a run with no frames fails later, after
    writing), or an argparse usage dump (two lines)."""
    out = tmp_path / "out"
    code = cli.main(["run", "--techniques", "sm", "--out", str(out), *args])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and message in err, err
    assert not out.exists()


def test_unknown_statistics_in_an_experiment_names_file_and_line(tmp_path, capsys):
    """Catches: a statistics key accepted with any value, or not known to the schema."""
    path = tmp_path / "exp.yaml"
    path.write_text("techniques: all\nstatistics: mean\n")
    code = cli.main(["run", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert f"{path}:2: statistics: Input should be 'order' or 'bootstrap'" in err


def test_summary_warns_about_noisy_runs_and_retime_replaces_them(tmp_path, small_scene_file,
                                                                  monkeypatch, capsys, gl_context):
    """With the threshold below any load every run is noisy: the summary names how many, and
    --retime-noisy measures them again (new frame times) and records how many it retimed.
    With the threshold above any load there is no warning.

    Catches: a warning that ignores the 5% rule or miscounts, and --retime-noisy that
    renders nothing again (rows unchanged)."""
    scene_file = small_scene_file("box_plane")
    args = ["run", "--scene-file", str(scene_file), "--techniques", "sm,pcf", "--frames", "3",
            "--warmup", "0", "--quiet"]
    monkeypatch.setattr(runner, "NOISY_CONTENTION", 1.0)
    assert cli.main([*args, "--out", str(tmp_path / "quiet")]) == 0
    assert "warning" not in capsys.readouterr().err

    monkeypatch.setattr(runner, "NOISY_CONTENTION", -1.0)
    out = tmp_path / "busy"
    assert cli.main([*args, "--out", str(out)]) == 0
    assert "warning: 2 of 2 runs are noisy" in capsys.readouterr().err
    first = rows_by_run_id(out)
    assert all(r["noisy"] == "1" for r in first.values())
    assert cli.main([*args, "--out", str(out), "--retime-noisy"]) == 0
    again = rows_by_run_id(out)
    assert again.keys() == first.keys()
    for run_id, row in again.items():
        assert row["frame_ms"] != first[run_id]["frame_ms"]
        assert row["mae"] == first[run_id]["mae"]  # same output, timed again
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["invocations"][-1]["runs_retimed"] == 2
