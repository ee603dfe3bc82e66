"""Discovery through entry points, and the technique contract every registered one keeps."""

import ast
import inspect
import re
import tomllib
from importlib.metadata import EntryPoint
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

import techniques as techniques_package
from harness.technique import registry
from harness.technique.code_version import code_files
from harness.technique import Technique

from helpers import run_contract


def test_builtins_register_through_the_entry_point_group():
    from importlib.metadata import entry_points

    names = {ep.name for ep in entry_points(group=registry.GROUP)}
    assert {"sm", "pcf"} <= names
    assert set(registry.techniques()) == names


def test_the_distribution_has_a_name_of_its_own_and_plugins_depend_on_it():
    """``shadowbench`` on PyPI (0.2.1) is another project: a plugin depending on it would
    install that one. The project's distribution is registry.DISTRIBUTION; the template and
    the test plugins depend on it; the built-ins' installed distribution (whatever name this
    environment installed it under) is no plugin. Catches the name left ``shadowbench``."""
    root = Path(__file__).resolve().parents[2]
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    assert project["name"] == registry.DISTRIBUTION == "hard-shadow-bench"
    assert project["scripts"] == {"shadowbench": "harness.cli:main"}
    assert f"{registry.DISTRIBUTION}[dask]" in project["optional-dependencies"]["dev"]
    plugins = [root / "examples" / "plugin", *(root / "tests" / "data" / "plugins").iterdir()]
    for plugin in plugins:
        needs = tomllib.loads((plugin / "pyproject.toml").read_text())["project"]["dependencies"]
        assert needs == [registry.DISTRIBUTION], plugin
    assert registry.own_distribution() == registry.distribution_of("sm")
    assert not registry.is_plugin("sm") and not registry.is_plugin("ptsv")


def test_duplicate_names_are_an_error(monkeypatch):
    """Both are left out and the name is broken, an error where a command asks for it."""
    eps = [EntryPoint("sm", "techniques.sm:ShadowMap", registry.GROUP),
           EntryPoint("sm", "techniques.pcf:PercentageCloserFiltering", registry.GROUP)]
    monkeypatch.setattr(registry, "entry_points", lambda group: eps)
    registry.techniques.cache_clear()
    try:
        assert registry.techniques() == {}
        assert "registered twice" in registry.broken()["sm"]
        with pytest.raises(registry.RegistryError, match="'sm' is broken: .*registered twice"):
            registry.get("sm")
    finally:
        monkeypatch.undo()
        registry.techniques.cache_clear()


def test_entry_point_name_must_match_class_name(monkeypatch):
    eps = [EntryPoint("shadowmap", "techniques.sm:ShadowMap", registry.GROUP)]
    monkeypatch.setattr(registry, "entry_points", lambda group: eps)
    registry.techniques.cache_clear()
    try:
        assert "whose name is 'sm'" in registry.broken()["shadowmap"]
    finally:
        monkeypatch.undo()
        registry.techniques.cache_clear()


def test_one_baseline_at_most(monkeypatch):
    """sm is the built-ins' baseline (the dashboard divides costs by its); a second technique
    declaring itself one is an error naming both. Catches the baseline chosen silently."""
    assert registry.baseline() == "sm"
    monkeypatch.setattr(registry.get("pcf"), "baseline", True)
    own = re.escape(registry.own_distribution())
    with pytest.raises(registry.RegistryError,
                       match=rf"pcf \(distribution {own}\), sm \(distribution {own}\) "
                             "each declare baseline = True in their class; one baseline at most"):
        registry.baseline()


@pytest.mark.parametrize("declined, message", [
    ({"Point": "no cube map"}, "declines_lights.Point: not a light type"),
    ({"point": ""}, "declines_lights.point: needs the reason"),
])
def test_declined_lights_name_light_types_with_a_reason(declined, message, monkeypatch):
    """Catches a misspelt light type (the technique then runs on the light it meant to decline)
    or a skip with no reason for its row."""
    monkeypatch.setattr(registry.get("pcf"), "declines_lights", declined)
    registry.techniques.cache_clear()
    try:
        assert "pcf" not in registry.techniques()
        with pytest.raises(registry.RegistryError, match=message):
            registry.get("pcf")
    finally:
        monkeypatch.undo()
        registry.techniques.cache_clear()


TECHNIQUES = list(registry.techniques())
TECHNIQUE_DIR = Path(techniques_package.__file__).resolve().parent
def check_output(name, output, height, width):
    v = output.visibility
    assert isinstance(v, np.ndarray) and v.dtype == np.float32, (name, type(v), v.dtype)
    assert v.shape == (height, width), (name, v.shape)
    assert not np.isnan(v).any(), f"{name}: NaN in V"
    assert v.min() >= 0.0 and v.max() <= 1.0, (name, v.min(), v.max())
    assert output.mem_bytes >= 0, (name, output.mem_bytes)
    assert output.fetches_per_px >= 0, (name, output.fetches_per_px)


@pytest.mark.parametrize("scene_name", ["box_plane", "sphere_plane"])
@pytest.mark.parametrize("name", TECHNIQUES)
def test_technique_contract(name, scene_name, gl_context, scene_at):
    """Every registered technique renders V of the frame's shape in [0, 1] through at least one
    measured pass, reports non-negative costs and frees every GL object it made. Directional
    box_plane suits all of them; on the spot-lit sphere_plane a technique may be NotApplicable."""
    cls = registry.get(name)
    width, height = 48, 32
    scene = scene_at(scene_name, width, height)
    outputs, passes = run_contract(cls, scene)
    if outputs is None:
        assert scene_name != "box_plane", f"{name} must apply to a directional light"
        pytest.skip(f"{name} does not apply to {scene_name}")
    for output in outputs:
        check_output(name, output, height, width)
    assert passes, f"{name}: no measured pass"


@pytest.mark.parametrize("name", TECHNIQUES)
def test_technique_declaration(name):
    cls = registry.get(name)
    assert issubclass(cls, Technique)
    assert cls.summary and cls.paper
    doc = cls.__doc__ or ""
    for param in cls.Params.model_fields:
        assert f"``{param}``" in doc, f"{name}: parameter {param} missing from the docstring table"
    cls.Params()  # defaults are valid
    # a built-in has a quality curve (checked against Params when registered)
    assert cls.quality_knobs, f"{name}: declares no quality knob"
    with pytest.raises(ValidationError, match="no_such_parameter"):
        cls.Params(no_such_parameter=1)
    version = cls.code_version()
    assert len(version) == 12 and all(c in "0123456789abcdef" for c in version)


def package_imports(path: Path) -> set[Path]:
    """The ``techniques/**.py`` modules ``path`` imports, resolved by file path alone (an
    oracle independent of harness.technique.code_version's importlib resolution): ``from . import x``,
    ``from .x import y``, ``from ..common.x import y``, ``from techniques.a.b import y``,
    ``import techniques.a.b``."""
    def module_file(parts: list[str]) -> Path | None:
        for candidate in (TECHNIQUE_DIR.joinpath(*parts).with_suffix(".py"),
                          TECHNIQUE_DIR.joinpath(*parts, "__init__.py")):
            if parts and candidate.is_file():
                return candidate
        return None

    package = path.parent.relative_to(TECHNIQUE_DIR).parts
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        targets = []
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(package[:len(package) - (node.level - 1)])
            elif (node.module or "").split(".")[0] == "techniques":
                base = []
            else:
                continue
            module = [p for p in (node.module or "").split(".") if p]
            if not node.level:
                module = module[1:]
            targets = [base + module] + [base + module + [a.name] for a in node.names]
        elif isinstance(node, ast.Import):
            targets = [a.name.split(".")[1:] for a in node.names
                       if a.name.split(".")[0] == "techniques"]
        found |= {f for f in map(module_file, targets) if f is not None}
    return found


@pytest.mark.parametrize("name", TECHNIQUES)
def test_code_version_covers_imported_package_modules(name):
    """A change to a module a technique imports (its own package's, or techniques.common's,
    directly or through another) changes its code version. Catches the old sibling-only
    regex, which after the move to packages missed techniques/common/light_maps.py (tried)."""
    source = Path(inspect.getsourcefile(registry.get(name))).resolve()
    hashed = set(code_files(registry.get(name).__module__))
    wanted, queue = set(), [source]
    while queue:
        for module in package_imports(queue.pop()) - wanted:
            wanted.add(module)
            queue.append(module)
    missing = [str(m.relative_to(TECHNIQUE_DIR)) for m in sorted(wanted) if m not in hashed]
    assert not missing, f"{name}: code version ignores imported {missing}"


def test_unknown_technique_lists_registered():
    with pytest.raises(KeyError, match="registered: .*pcf"):
        registry.get("nope")
