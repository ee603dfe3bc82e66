"""Discovery through entry points, and the technique contract every registered one keeps."""

from importlib.metadata import EntryPoint

import pytest

from harness import registry
from harness.technique import Technique


def test_builtins_register_through_the_entry_point_group():
    from importlib.metadata import entry_points

    names = {ep.name for ep in entry_points(group=registry.GROUP)}
    assert {"sm", "pcf"} <= names
    assert set(registry.techniques()) == names


def test_duplicate_names_are_an_error(monkeypatch):
    eps = [EntryPoint("sm", "techniques.sm:ShadowMap", registry.GROUP),
           EntryPoint("sm", "techniques.pcf:PercentageCloserFiltering", registry.GROUP)]
    monkeypatch.setattr(registry, "entry_points", lambda group: eps)
    registry.techniques.cache_clear()
    try:
        with pytest.raises(registry.RegistryError, match="registered twice"):
            registry.techniques()
    finally:
        monkeypatch.undo()
        registry.techniques.cache_clear()


def test_entry_point_name_must_match_class_name(monkeypatch):
    eps = [EntryPoint("shadowmap", "techniques.sm:ShadowMap", registry.GROUP)]
    monkeypatch.setattr(registry, "entry_points", lambda group: eps)
    registry.techniques.cache_clear()
    try:
        with pytest.raises(registry.RegistryError, match="whose name is 'sm'"):
            registry.techniques()
    finally:
        monkeypatch.undo()
        registry.techniques.cache_clear()


@pytest.mark.parametrize("name", list(registry.techniques()))
def test_technique_contract(name):
    cls = registry.get(name)
    assert issubclass(cls, Technique)
    assert cls.summary and cls.paper
    doc = cls.__doc__ or ""
    for param in cls.Params.model_fields:
        assert f"``{param}``" in doc, f"{name}: parameter {param} missing from the docstring table"
    cls.Params()  # defaults are valid
    with pytest.raises(Exception):
        cls.Params(no_such_parameter=1)
    assert cls.code_version() == cls.code_version() and len(cls.code_version()) == 12


def test_unknown_technique_lists_registered():
    with pytest.raises(KeyError, match="registered: .*pcf"):
        registry.get("nope")
