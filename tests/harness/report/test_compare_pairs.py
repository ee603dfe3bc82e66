"""shadowbench compare after a changed setting: a run found in one folder only is paired with
the other's run of the same scene, size and technique, shown with its changed parameters and
the same columns as a run in common, and counted in the exit status when it got worse."""

from __future__ import annotations

from harness.cli import main as shadowbench
from harness.report import compare



def timed(ms: float) -> dict:
    """A time with an interval 10% either side (a quiet machine's)."""
    return {"time_ms": ms, "time_ms_ci_low": 0.9 * ms, "time_ms_ci_high": 1.1 * ms, "noisy": 0}


# sm at res 512 and 1024 in both folders; A's third run is res 2048 at 5 ms
COMMON = [{"params": {"res": 512}, **timed(2.0)}, {"params": {"res": 1024}, **timed(3.0)}]
A_ONLY = [{"params": {"res": 2048}, **timed(5.0)},
          {"params": {"res": 512}, "scene": "elsewhere", **timed(1.0)}]
# B ran res 2048 with bias 0.05 instead (one change, 8 ms: worse) and res 4096 with bias 0.05
# (two changes from A's res-2048 run: not its pair)
B_ONLY = [{"params": {"res": 4096, "bias": 0.05}, **timed(9.0)},
          {"params": {"res": 2048, "bias": 0.05}, **timed(8.0)}]


def test_a_changed_parameter_is_paired_and_a_worse_pair_exits_1(tmp_path, make_results, capsys):
    """Catches the compare that matched by parameters only: it reported "2 runs in common",
    0 worse and exit 0 (tried), never saying that bias changed nor what it did to the time."""
    a = make_results(tmp_path / "a", COMMON + A_ONLY)
    b = make_results(tmp_path / "b", COMMON + B_ONLY)
    page = tmp_path / "diff.html"
    assert shadowbench(["compare", str(a), str(b), "--html", str(page)]) == 1
    out = capsys.readouterr().out
    pair = [line for line in out.splitlines() if "changed bias" in line]
    assert len(pair) == 1 and pair[0].startswith("*"), out
    assert pair[0].endswith("res=2048; changed bias: 0.02 → 0.05"), pair[0]
    assert pair[0].split()[4:8] == ["5", "→", "8", "1.60"], pair[0]
    assert "2 runs in common, 1 paired with changed parameters" in out and "1 worse" in out
    unpaired = out[out.index("unpaired:"):]
    assert f"only in {a}, unpaired:\n  elsewhere 32x32 sm " in out
    assert f"only in {b}, unpaired:\n  s 32x32 sm " in out and "res=4096" in unpaired
    c = compare.compare(a, b)
    [row] = [r for r in c.rows if r["changed"]]
    assert row["changed"] == "bias: 0.02 → 0.05" and row["ratio"] == 1.6
    assert row["time"][0][0] == 5.0 and row["time"][1][0] == 8.0
    assert row["changes"]["time_ms"] == "worse" and row["verdict"] == "worse"
    html = page.read_text()
    assert "changed bias: 0.02 → 0.05" in html and "res=4096" in html and "elsewhere" in html


def test_a_better_pair_exits_0_and_the_messages_name_the_users_paths(tmp_path, make_results,
                                                                        capsys):
    """The changed run is faster in B: paired, better, exit 0. A --html path in a missing
    folder exits 2 naming that path, not the temporary file it would be written through.
    Catches a pair counted as worse whatever its direction, and the old message that named
    `.diff.html.<hex>.tmp`."""
    a = make_results(tmp_path / "a", COMMON + A_ONLY[:1])
    b = make_results(tmp_path / "b", COMMON + [{**B_ONLY[1], **timed(2.5)}])
    assert shadowbench(["compare", str(a), str(b)]) == 0
    assert "1 paired with changed parameters" in capsys.readouterr().out
    missing = tmp_path / "no" / "diff.html"
    assert shadowbench(["compare", str(a), str(b), "--html", str(missing)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"shadowbench: --html {missing}: No such file or directory"], err
