"""compare and noise (issue 47, friction 6): a time is worse or better only outside both runs'
intervals with neither run noisy, and the line says why where it cannot tell; identical
settings are one run, never a change of settings; only what got worse is starred; a line names
the parameters that tell runs apart or changed, not all of them."""

from __future__ import annotations

from harness.cli import main as shadowbench
from harness.report import compare


def timed(ms: float, *, noisy: int = 0, spread: float = 0.1) -> dict:
    return {"time_ms": ms, "time_ms_ci_low": (1 - spread) * ms,
            "time_ms_ci_high": (1 + spread) * ms, "noisy": noisy}


def table(out: str) -> list[str]:
    """The table's lines, its heading first, without the summary and unpaired lists."""
    lines = out.splitlines()
    return lines[:next(i for i, line in enumerate(lines) if "runs in common" in line)]


def test_noisy_runs_with_identical_settings_are_not_better(tmp_path, make_results, capsys):
    """The issue's folders: identical settings, times 0.5x with intervals apart, both runs
    noisy (timed while the machine was busy). Catches the compare that called them better
    (tried: "1 better")."""
    a = make_results(tmp_path / "a", [{"params": {"res": 512}, **timed(8.0, noisy=1)}])
    b = make_results(tmp_path / "b", [{"params": {"res": 512}, **timed(4.0, noisy=1)}])
    assert shadowbench(["compare", str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert "0 worse, 0 better, 1 undecided" in out, out
    [line] = table(out)[1:]
    assert "? noisy" in line and "0.50" in line and "*" not in line
    [row] = compare.compare(a, b).rows
    assert row["verdict"] == "undecided" and row["changes"]["time_ms"] == "undecided"


def test_a_time_without_an_interval_or_inside_one_is_undecided(tmp_path, make_results):
    """1.5x slower: without intervals, with a one-frame run's interval of no width, and with
    A's median inside B's interval: each undecided, saying why; with the intervals apart and
    both quiet, worse. Catches a compare that decides on the ratio alone where it has no
    interval (tried: 2 worse)."""
    runs_a = [{"params": {"res": 512}, "time_ms": 2.0},
              {"params": {"res": 1024}, "time_ms": 2.0, "time_ms_ci_low": 2.0,
               "time_ms_ci_high": 2.0},
              {"params": {"res": 2048}, **timed(2.0)},
              {"params": {"res": 4096}, **timed(2.0)}]
    runs_b = [{"params": {"res": 512}, "time_ms": 3.0},
              {"params": {"res": 1024}, "time_ms": 3.0, "time_ms_ci_low": 3.0,
               "time_ms_ci_high": 3.0},
              {"params": {"res": 2048}, **timed(3.0, spread=0.4)},
              {"params": {"res": 4096}, **timed(3.0)}]
    c = compare.compare(make_results(tmp_path / "a", runs_a), make_results(tmp_path / "b", runs_b))
    assert c.worse == 1
    why = {r["setting"]: (r["verdict"], r["undecided"]) for r in c.rows}
    assert why == {"res=512": ("undecided", "no interval"),
                   "res=1024": ("undecided", "no interval"),
                   "res=2048": ("undecided", "inside an interval"),
                   "res=4096": ("worse", "")}, why
    assert c.undecided == 3


def test_only_what_got_worse_is_starred(tmp_path, make_results, capsys):
    """res 512's edge error shrinks (A's V shifted, B's not) and res 1024's grows: the first
    line shows its change without a star, the second with one. Catches improvements starred
    like regressions (tried)."""
    a = make_results(tmp_path / "a", [{"params": {"res": 512}, "shift": 1, **timed(2.0)},
                                      {"params": {"res": 1024}, **timed(2.0)}])
    b = make_results(tmp_path / "b", [{"params": {"res": 512}, **timed(2.0)},
                                      {"params": {"res": 1024}, "shift": 1, **timed(2.0)}])
    assert shadowbench(["compare", str(a), str(b)]) == 1
    lines = {res: line for line in table(capsys.readouterr().out)[1:]
             for res in ("res=512", "res=1024") if f"{res}," in f"{line},"}
    assert "→" in lines["res=512"] and "*" not in lines["res=512"], lines
    assert lines["res=1024"].startswith("*") and lines["res=1024"].count("*") == 4, lines


def test_identical_settings_are_one_run_and_lines_stay_short(tmp_path, make_results, capsys):
    """B wrote res 512 as 512.0 (the same setting): a run in common, not a pair with nothing
    changed; and a line names only what tells the runs apart (res), not sm's other parameters.
    Catches the 330-character lines that printed every parameter (tried) and a pair of
    identical settings."""
    a = make_results(tmp_path / "a", [{"params": {"res": 512}, **timed(2.0)},
                                      {"params": {"res": 1024}, **timed(2.0)}])
    b = make_results(tmp_path / "b", [{"params": {"res": 512.0}, **timed(2.0)},
                                      {"params": {"res": 1024}, **timed(2.0)}])
    assert shadowbench(["compare", str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert "2 runs in common, 0 paired" in out, out
    for line in table(out):
        assert len(line) <= 100, line
        assert "slope_bias" not in line and "normal_offset" not in line, line
    c = compare.compare(a, b)
    assert [r["changed"] for r in c.rows] == ["", ""]
