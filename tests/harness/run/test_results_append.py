"""results.csv grows by appending a finished run's row (harness.results.record_rows): the file a
sweep of n runs leaves is the one n replacements left, a run's row is never written twice, and
what cannot be appended (a new column, a run stored before, a last line without its end, a
short write) leaves the file whole."""

from __future__ import annotations

import csv
import errno
import os

import pytest

from harness import results


def _row(run_id: str, **values) -> dict:
    return {"run_id": run_id, "schema": results.SCHEMA_VERSION, "scene": "s", "technique": "sm",
            "params": {"res": 1024, "bias": 0.5}, "status": "ok", "width": 64, "height": 48,
            "time_ms": 1.25, "frame_ms": [1.0, 1.5], "edge_mae": float("nan"), **values}


def _replaced(folder, rows) -> bytes:
    """The file as one replacement of it (write_rows) writes these rows."""
    folder.mkdir()
    results.write_rows(folder, rows)
    return (folder / results.RESULTS_FILE).read_bytes()


def test_rows_are_appended_in_place_and_give_the_file_a_rewrite_gives(tmp_path, monkeypatch):
    """Three runs recorded one by one: the file is written whole once, for the first, and
    appended to after; it is byte for byte what write_rows of the three writes. Catches
    record_rows rewriting the whole file for every run (make bench rewrote 160,000 rows for
    its 563 runs) and an append under other columns or in another order."""
    rows = [_row(f"{i:016d}") for i in range(3)]
    replaced = []
    write_rows = results.write_rows
    monkeypatch.setattr(results, "write_rows", lambda *a: replaced.append(a) or write_rows(*a))
    for row in rows:
        results.record_row(tmp_path, row)
    assert len(replaced) == 1
    monkeypatch.undo()
    assert (tmp_path / results.RESULTS_FILE).read_bytes() == _replaced(tmp_path / "b", rows)
    assert [r["run_id"] for r in results.read_rows(tmp_path)] == [r["run_id"] for r in rows]


def test_a_run_stored_again_replaces_its_row(tmp_path):
    """A failed run retried: its row is replaced, not appended beside the old one."""
    results.record_rows(tmp_path, [_row("a" * 16, status="error", error="boom"), _row("b" * 16)])
    results.record_row(tmp_path, _row("a" * 16))
    stored = results.read_rows(tmp_path)
    assert [(r["run_id"], r["status"]) for r in stored] == [("b" * 16, "ok"), ("a" * 16, "ok")]


def test_a_value_for_a_column_the_file_lacks_rewrites_it_with_the_column(tmp_path):
    """A plugin's extra column arrives with a later run: the file is replaced with the column
    (every earlier row empty there). Catches an append that drops the value (extrasaction)."""
    results.record_row(tmp_path, _row("a" * 16))
    results.record_row(tmp_path, _row("b" * 16, my_plugin_count=7))
    stored = results.read_rows(tmp_path)
    assert [r["my_plugin_count"] for r in stored] == ["", "7"]


def test_a_last_line_without_its_end_is_not_joined(tmp_path):
    """A file whose last line lost its line end (edited by hand): the next row is not glued to
    it; both rows read back whole."""
    results.record_row(tmp_path, _row("a" * 16))
    path = tmp_path / results.RESULTS_FILE
    path.write_bytes(path.read_bytes().rstrip(b"\r\n"))
    results.record_row(tmp_path, _row("b" * 16))
    assert [r["run_id"] for r in results.read_rows(tmp_path)] == ["a" * 16, "b" * 16]
    assert {r["status"] for r in results.read_rows(tmp_path)} == {"ok"}


@pytest.mark.parametrize("short", [True, False], ids=["short write", "write fails"])
def test_a_write_that_falls_short_leaves_the_file_as_it_was(tmp_path, monkeypatch, short):
    """A full disk in the middle of an append: an OSError naming results.csv, and the file as it
    was before (no half row for the next read to misparse). Catches the short write left in
    place (a torn last line: the next run's row joined to it)."""
    results.record_row(tmp_path, _row("a" * 16))
    path = tmp_path / results.RESULTS_FILE
    before = path.read_bytes()
    real_write = os.write

    def full_disk(fd, data):
        if not short:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_write(fd, data[:len(data) // 2])

    monkeypatch.setattr(os, "write", full_disk)
    with pytest.raises(OSError) as raised:
        results.record_row(tmp_path, _row("b" * 16))
    monkeypatch.undo()
    assert raised.value.errno == errno.ENOSPC and raised.value.filename == str(path)
    assert path.read_bytes() == before
    results.record_row(tmp_path, _row("c" * 16))
    with path.open(newline="") as f:
        assert [r["run_id"] for r in csv.DictReader(f)] == ["a" * 16, "c" * 16]
