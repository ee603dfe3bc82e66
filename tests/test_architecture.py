"""The layer contract of DESIGN.md, declared in pyproject.toml, checked by import-linter."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
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
    assert "1 kept, 0 broken" in proc.stdout


def test_an_upward_import_breaks_the_contract(tmp_path):
    """Catches a contract that checks nothing (no layers, or a layer list that leaves config
    out): config, at the bottom, importing the run package must fail."""
    tree = _copy(tmp_path)
    with (tree / "harness" / "config" / "limits.py").open("a") as f:
        f.write("\nfrom harness.run import plan  # noqa: E402,F401\n")
    proc = _lint(tree)
    assert proc.returncode != 0
    assert "harness.config.limits -> harness.run.plan" in proc.stdout
