"""The layer contract of docs/architecture.md, declared in pyproject.toml, checked by import-linter."""

from __future__ import annotations

import ast
import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

from helpers import ROOT

LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def _lint(tree: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    return subprocess.run([str(LINT_IMPORTS), "--no-cache"], cwd=tree, env=env,
                          capture_output=True, text=True, timeout=120)


def _copy(tmp_path: Path) -> Path:
    for name in ("harness", "techniques", "papers"):
        shutil.copytree(ROOT / name, tmp_path / name,
                        ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    return tmp_path


def test_every_module_imports_only_below_its_layer(tmp_path):
    proc = _lint(_copy(tmp_path))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "2 kept, 0 broken" in proc.stdout


def test_an_upward_import_breaks_the_contract(tmp_path):
    """Catches a contract that checks nothing (no layers, or a layer list that leaves config
    out): config, at the bottom, importing the run package must fail."""
    tree = _copy(tmp_path)
    with (tree / "harness" / "config" / "limits.py").open("a") as f:
        f.write("\nfrom harness.run import plan  # noqa: E402,F401\n")
    proc = _lint(tree)
    assert proc.returncode != 0
    assert "harness.config.limits -> harness.run.plan" in proc.stdout


def test_a_technique_package_importing_another_breaks_the_contract(tmp_path):
    """The independence contract: sv importing silhouette's edge code fails lint-imports.
    Catches a contract that lists no packages, or leaves sv out."""
    tree = _copy(tmp_path)
    with (tree / "techniques" / "sv" / "sv_volumes.py").open("a") as f:
        f.write("\nfrom techniques.silhouette import silhouette_edges  # noqa: E402,F401\n")
    proc = _lint(tree)
    assert proc.returncode != 0
    assert "techniques.sv.sv_volumes -> techniques.silhouette.silhouette_edges" in proc.stdout


VERSIONS = """
from harness.technique import registry
print(*(registry.get(n).code_version() for n in ("sm", "pcf", "sv")))
"""


def _versions(tree: Path) -> list[str]:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    proc = subprocess.run([sys.executable, "-c", VERSIONS], cwd=tree, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.split()


def test_editing_a_shared_shader_changes_the_versions_of_the_techniques_that_include_it(
        tmp_path):
    """techniques/common/shadow_map.glsl, included by sm's and pcf's shading shaders through
    ``#include "../common/shadow_map.glsl"``, is part of their code version and not of sv's
    (which never includes it). Catches the flat-folder hash of before the move, which follows
    only imports and shaders beside the technique's module (all three unchanged: stored
    results silently reused; tried), and one that hashes every file of techniques/ (sv rerun
    for a change it never runs)."""
    tree = _copy(tmp_path)
    before = _versions(tree)
    with (tree / "techniques" / "common" / "shadow_map.glsl").open("a") as f:
        f.write("\n// an edit\n")
    after = _versions(tree)
    assert [b != a for b, a in zip(before, after)] == [True, True, False]


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the project modules it imports anywhere in its text (under TYPE_CHECKING and
    inside functions too). A child's import of its own package counts: where a package's
    ``__init__`` is its main module (harness.scene, harness.technique), a child importing it
    while it imports the child is a cycle."""
    modules = {}
    for top in ("harness", "techniques", "papers"):
        for path in (root / top).rglob("*.py"):
            name = ".".join(path.relative_to(root).with_suffix("").parts)
            modules[name.removesuffix(".__init__")] = path
    graph = {name: set() for name in modules}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = (importlib.util.resolve_name("." * node.level + (node.module or ""), package)
                        if node.level else node.module)
                # a submodule imported by name needs its package only as a namespace
                targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                           for alias in node.names]
            else:
                continue
            for target in targets:
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                if target and target != name:
                    graph[name].add(target)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while not component or component[-1] != v:
                component.append(stack.pop())
                on_stack.discard(component[-1])
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycle_type_only_imports_included():
    """No two modules import each other, directly or around a loop, counting imports under
    TYPE_CHECKING (import-linter's layers leave a cycle inside one layer alone). Catches
    harness.config.mesh_files importing scene_schema's MeshFile for its annotations while
    scene_schema imports mesh_files (the cycle before issue 31; found by this test on that
    commit), and harness/scene/__init__.py importing transforms, which imports the scene's
    classes from it (tried on the rooms of issue 51)."""
    assert cycles(import_graph(ROOT)) == []


def test_the_cycle_finder_finds_a_type_only_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(graph) == [["a", "b", "c"]]


def test_the_independence_contract_names_every_technique_package():
    """Every package under techniques/ but common is in the independence contract, so a new
    technique cannot import another unseen. Catches a package added without its line
    (techniques.rt was, until this test)."""
    import tomllib

    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    (independent,) = [c for c in contracts["contracts"] if c["type"] == "independence"]
    packages = {f"techniques.{p.name}" for p in (ROOT / "techniques").iterdir()
                if (p / "__init__.py").is_file() and p.name != "common"}
    assert set(independent["modules"]) == packages


def private_names_used_across_modules(root: Path) -> list[str]:
    """``module: name`` for each underscore name a module imports from, or reads off, another
    project module (``from .x import _y``, ``x._y(...)`` on an imported project module)."""
    found = []
    for top in ("harness", "techniques", "papers"):
        for path in (root / top).rglob("*.py"):
            module = ".".join(path.relative_to(root).with_suffix("").parts)
            tree = ast.parse(path.read_text())
            imported = set()
            for node in ast.walk(tree):
                if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").split(
                        ".")[0] in ("harness", "techniques", "papers")):
                    for alias in node.names:
                        imported.add(alias.asname or alias.name)
                        if alias.name.startswith("_") and not alias.name.startswith("__"):
                            found.append(f"{module}: {alias.name}")
            for node in ast.walk(tree):
                if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                        and node.value.id in imported and node.attr.startswith("_")
                        and not node.attr.startswith("__")):
                    found.append(f"{module}: {node.value.id}.{node.attr}")
    return sorted(set(found))


def test_names_used_across_modules_are_public():
    """No module reaches into another's underscore names. Catches measure.py importing
    score.py's seven private helpers and sweep.py and cli.py using store._exclusive (as before
    issue 31; found by this test then)."""
    assert private_names_used_across_modules(ROOT) == []
