"""shadowbench compare A B on results folders written by hand: no change, a slower run, a worse
error, a run that stopped working, and the bad inputs that exit 2 with one line."""

from __future__ import annotations

from harness import results
from harness.cli import main as shadowbench
from harness.report import compare

# three sm runs (res 512, 1024, 2048): the first with a timing interval, the last shifted so it
# has an edge error
RUNS = [{"params": {"res": 512}, "time_ms": 2.0, "time_ms_ci_low": 1.9, "time_ms_ci_high": 2.1},
        {"params": {"res": 1024}, "time_ms": 3.0},
        {"params": {"res": 2048}, "time_ms": 5.0, "shift": 1}]


def _with(runs, index, **change):
    return [({**r, **change} if i == index else r) for i, r in enumerate(runs)]


def test_a_folder_against_itself_reports_no_change(tmp_path, make_results, capsys):
    """The folder also holds an older row of the res-512 run (9 ms, superseded by the rerun
    written after it). Catches a comparison that does not take each run's latest row: it would
    pair the old row with the new one and flag a change."""
    folder = make_results(tmp_path / "a", RUNS)
    rows = results.read_rows(folder)
    results.write_rows(folder, [{**rows[0], "run_id": "f" * 16, "time_ms": 9.0}] + rows)
    assert shadowbench(["compare", str(folder), str(folder)]) == 0
    out = capsys.readouterr().out
    assert "3 runs in common" in out and "0 worse, 0 better" in out
    assert compare.compare(folder, folder).rows[0]["ratio"] == 1.0


def test_a_slower_run_beyond_its_interval_is_flagged(tmp_path, make_results, capsys):
    """B's res-512 run takes 2.6 ms, its interval [2.5, 2.7] above A's [1.9, 2.1]: worse, exit 1.
    Catches a compare that ignores time or reads the ratio A / B."""
    a = make_results(tmp_path / "a", RUNS)
    b = make_results(tmp_path / "b", _with(RUNS, 0, time_ms=2.6, time_ms_ci_low=2.5,
                                           time_ms_ci_high=2.7))
    assert shadowbench(["compare", str(a), str(b)]) == 1
    worse = [line for line in capsys.readouterr().out.splitlines() if line.startswith("*")]
    assert len(worse) == 1 and "res=512" in worse[0] and "1.30" in worse[0]
    assert "slower *" in worse[0]


def test_a_slower_run_within_its_interval_or_the_factor_is_not(tmp_path, make_results):
    """1.3x slower but A's median inside B's interval: undecided; 1.05x slower without
    intervals: the same. Catches a compare that ignores the intervals or the factor."""
    a = make_results(tmp_path / "a", RUNS)
    b = make_results(tmp_path / "b", _with(_with(RUNS, 0, time_ms=2.6, time_ms_ci_low=2.0,
                                                 time_ms_ci_high=3.2), 1, time_ms=3.15))
    c = compare.compare(a, b)
    assert c.worse == 0
    assert sorted(r["changes"]["time_ms"] for r in c.rows) == ["same", "same", "undecided"]
    assert c.rows[0]["undecided"] == "inside an interval"  # undecided sorts before same
    # the run without intervals, 1.05x, beyond a factor of 1.02: it cannot be told
    again = compare.compare(a, b, factor=1.02)
    assert again.worse == 0 and again.undecided == 2


def test_a_worse_error_and_a_failed_run_are_flagged(tmp_path, make_results, capsys):
    """The res-1024 run is shifted by 2 px in B (edge_mae, mae, wrong_pct grow) and the res-2048
    run failed: two worse runs, exit 1, and --html writes the same as a page. Catches a compare
    that looks only at time, or misses a run that stopped working."""
    a = make_results(tmp_path / "a", RUNS)
    b = make_results(tmp_path / "b", _with(_with(RUNS, 1, shift=2), 2, status="error",
                                           error="RuntimeError: boom"))
    page = tmp_path / "diff.html"
    assert shadowbench(["compare", str(a), str(b), "--html", str(page)]) == 1
    out = capsys.readouterr().out
    assert "2 worse" in out
    c = compare.compare(a, b)
    by_res = {r["setting"].removeprefix("res="): r for r in c.rows}
    assert by_res["1024"]["changes"]["edge_mae"] == "worse"
    assert by_res["1024"]["errors"]["edge_mae"][0] == 0.0 < by_res["1024"]["errors"]["edge_mae"][1]
    assert by_res["2048"]["changes"]["status"] == "worse"
    assert "RuntimeError" not in page.read_text() and "ok → error" in page.read_text()


def test_bad_input_exits_2_with_one_line_naming_the_folder(tmp_path, make_results, capsys):
    """Catches tracebacks (KeyError on a foreign CSV, FileNotFoundError) and silent exit 0 on
    folders with nothing in common."""
    good = make_results(tmp_path / "good", RUNS)
    empty = tmp_path / "empty"
    empty.mkdir()
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "results.csv").write_text("name,value\nx,1\n")
    old = make_results(tmp_path / "old", RUNS)
    rows = results.read_rows(old)
    results.write_rows(old, [{**r, "schema": 0} for r in rows])
    other = make_results(tmp_path / "other", RUNS, scene="elsewhere")
    binary = tmp_path / "binary"
    binary.mkdir()
    (binary / "results.csv").write_bytes(b"\xff\xfe\x00\x81" * 50)
    cases = {empty: "no results.csv", foreign: "not a shadowbench results file",
             old: "results version [0]", other: "no run in common", binary: "not a shadowbench results file"}
    for folder, why in cases.items():
        assert shadowbench(["compare", str(good), str(folder)]) == 2, folder
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and why in err[0] and str(folder.name) in err[0], err
