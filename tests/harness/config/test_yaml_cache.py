"""read_yaml keeps what a file gave while the file is unchanged (harness/config/yaml_source.py):
load_scene reads its whole scene file for every scene it builds."""

from __future__ import annotations

import pytest
import yaml

from harness.config import ConfigError, read_yaml


@pytest.fixture
def counted_parses(monkeypatch):
    parses = []
    real_compose = yaml.compose
    monkeypatch.setattr(yaml, "compose", lambda *a, **k: parses.append(a) or real_compose(*a, **k))
    return parses


def test_an_unchanged_file_is_parsed_once(tmp_path, counted_parses):
    """Catches the file parsed again at each read (35 ms for scenes.yaml, a tenth of the
    technique tests' time)."""
    path = tmp_path / "s.yaml"
    path.write_text("scenes: {a: {resolution: [8, 8]}}\n")
    first, _ = read_yaml(path)
    again, _ = read_yaml(path)
    assert first == again == {"scenes": {"a": {"resolution": [8, 8]}}}
    assert len(counted_parses) == 1


def test_a_reader_changing_its_data_changes_no_later_read(tmp_path):
    """Catches the kept data handed out itself: a caller's change (a validator filling in a
    default) would reach every later reader."""
    path = tmp_path / "s.yaml"
    path.write_text("scenes: {a: {resolution: [8, 8]}}\n")
    for _ in range(2):  # the first read's data and a kept one's
        data, _ = read_yaml(path)
        data["scenes"]["a"]["resolution"].append(99)
        data["scenes"]["b"] = {}
        assert read_yaml(path)[0] == {"scenes": {"a": {"resolution": [8, 8]}}}


def test_an_edited_file_is_read_again(tmp_path, counted_parses):
    """The same size, written again (a new modification time), and then broken: each read
    gives what the file holds now. Catches a cache keyed by the path alone."""
    path = tmp_path / "s.yaml"
    path.write_text("scenes: {a: {resolution: [8, 8]}}\n")
    read_yaml(path)
    path.write_text("scenes: {b: {resolution: [9, 9]}}\n")
    assert read_yaml(path)[0] == {"scenes": {"b": {"resolution": [9, 9]}}}
    path.write_text("scenes: {b: [\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        read_yaml(path)
