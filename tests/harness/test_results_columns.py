"""A results file that explains itself (issue 35): every column documented in docs/results.md,
generated from the schema; old folders still load; JSON columns parsed; stale rows dropped."""

import csv
import json
from pathlib import Path

from harness.results import columns
from harness import results
from helpers import ROOT



def test_the_page_is_the_schema():
    """docs/results.md is what ``python -m harness.results.columns`` writes, and every column has its
    unit-or-dash, meaning and when-empty. Catches a column added to the schema without its
    line (a Column with no meaning), and a page edited by hand or not regenerated."""
    for c in columns.COLUMN_TABLE:
        assert c.meaning.strip() and c.empty.strip(), c.name
    assert set(results.COLUMNS) == {c.name for c in columns.COLUMN_TABLE}
    page = (ROOT / "docs" / "results.md").read_text()
    assert page == columns.page(), "docs/results.md is stale: python -m harness.results.columns > " \
                                   "docs/results.md"
    documented = [line.split("`")[1] for line in page.splitlines() if line.startswith("| `")]
    assert documented == list(results.COLUMNS)


def _write(folder: Path, header: list[str], rows: list[dict]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    with (folder / results.RESULTS_FILE).open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=header)
        writer.writeheader()
        writer.writerows(rows)


def _row(**values) -> dict:
    return {"run_id": "r", "scene": "s", "technique": "sm", "params": '{"res": 1024}',
            "status": "ok", "width": "64", "height": "48", "code_version": "a" * 12,
            "frame_ms": "[1.5, 2.0]", "passes": '[{"name": "map", "ms": 1.0}]',
            "finished_at": "", **values}


def test_an_old_folder_loads_with_res_as_map_res_and_json_parsed(tmp_path):
    """A folder written before the rename (a ``res`` column) loads with ``map_res``; frame_ms
    and passes come back as lists. Catches the rename breaking old folders (no map_res) and the
    JSON columns left as text."""
    _write(tmp_path, list(_row()) + ["res"], [_row(res="1024.0")])
    df = results.load(tmp_path)
    assert "res" not in df.columns and df["map_res"].tolist() == [1024.0]
    assert df["frame_ms"].tolist() == [[1.5, 2.0]]
    assert df["passes"].tolist() == [[{"name": "map", "ms": 1.0}]]
    assert results.read_rows(tmp_path)[0]["map_res"] == "1024.0"


def test_stale_rows_are_dropped_by_default_and_flagged_on_request(tmp_path):
    """Three runs: sm at res 1024 by code a then b (the edit and the rerun), and at res 2048 by
    code a alone. The first is stale (a later row of the same run has another version); the
    2048 one is not (nothing newer of it). Catches stale rows kept by default (two rows of one
    run), a version compared across parameters (2048 dropped), and nothing flagged."""
    rows = [_row(run_id="1"), _row(run_id="2", code_version="b" * 12),
            _row(run_id="3", params='{"res": 2048}')]
    _write(tmp_path, list(rows[0]), rows)
    df = results.load(tmp_path)
    assert df["run_id"].tolist() == ["2", "3"] and "stale" not in df.columns
    flagged = results.load(tmp_path, stale="flag")
    assert flagged["stale"].tolist() == [True, False, False]
    assert json.dumps(flagged["params"][2]) == '{"res": 2048}'
