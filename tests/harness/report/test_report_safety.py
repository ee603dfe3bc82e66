"""A report of hostile results runs no script and reads and writes only inside its folder; a CSV
that is not results is one line. Each test names the broken code it catches."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import (
    HOSTILE_SCENE,
    HOSTILE_TECHNIQUE,
    assert_one_line,
    files_under,
    result_rows,
    run_cli,
    small_run,
)

from harness import cli, config, results


@pytest.mark.parametrize("content, needle", [
    ("", "no results"), ("run_id,scene,technique,params,status\n", "no results"),
    (bytes(range(256)), "not a shadowbench results file"),
    ("name,value\nfoo,1\n", "not a shadowbench results file"),
])
def test_report_on_a_csv_that_is_not_results(content, needle, tmp_path, capsys):
    """Before: EmptyDataError, ParserError and KeyError ('params') tracebacks."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.csv").write_bytes(content if isinstance(content, bytes) else content.encode())
    code, err = run_cli(["report", out], capsys)
    assert_one_line(code, err, 2, str(out / "results.csv"), needle)


@pytest.fixture(scope="module")
def hostile_results(tmp_path_factory, gl_context):
    """A results folder whose rows name a hostile scene and technique (as results copied from
    elsewhere or edited by hand would), with their arrays inside the folder. Returns the
    folder; its rows' names are HOSTILE_SCENE and HOSTILE_TECHNIQUE."""
    root = tmp_path_factory.mktemp("hostile")
    assert cli.main(small_run(root)) == 0
    out = root / "out"
    rows = result_rows(out)
    for row in rows:
        row.update(scene=HOSTILE_SCENE, technique=HOSTILE_TECHNIQUE)
    results.write_rows(out, rows)
    return out


def _files_outside(out: Path, before: set[Path]) -> set[Path]:
    return {p for p in files_under(out.parent) - before if out not in p.parents}


def test_a_report_of_hostile_names_runs_no_script_and_writes_only_in_the_folder(
        hostile_results):
    from harness import report

    before = files_under(hostile_results.parent)
    try:
        page = report.build_report(hostile_results).read_text()
    except config.ConfigError:
        page = ""  # refusing the rows is fine too
    assert not _files_outside(hostile_results, before)
    assert "onerror=\"document.title='PWNED'\"" not in page
    assert "<img src=x onerror=alert(1)>" not in page


def test_report_reads_arrays_only_from_inside_the_folder(tmp_path, monkeypatch, gl_context):
    from harness import report

    assert cli.main(small_run(tmp_path)) == 0
    out = tmp_path / "out"
    rows = result_rows(out)
    for row in rows:
        for column in ("array", "reference_array"):
            outside = tmp_path / f"outside-{column}.npz"
            outside.write_bytes((out / row[column]).read_bytes())
            row[column] = f"../{outside.name}"
    results.write_rows(out, rows)
    opened = []
    load = np.load
    monkeypatch.setattr(np, "load", lambda file, *a, **k: opened.append(Path(file)) or
                        load(file, *a, **k))
    try:
        report.build_report(out)
    except config.ConfigError:
        pass  # refusing the rows is fine too
    assert all(out.resolve() in p.resolve().parents for p in opened)
