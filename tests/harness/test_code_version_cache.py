"""code_hash is kept for the process while the files it read are unchanged
(harness/technique/code_version.py): a second call reads no module again, and an edit of any
file it followed, Python or shader, gives the new hash at the next call."""

from __future__ import annotations

import ast
import sys

import pytest

from harness.technique import code_version


@pytest.fixture
def package(tmp_path, monkeypatch):
    """A technique-like package: its module imports a helper module, which names a shader."""
    root = tmp_path / "cached_technique_pkg"
    root.mkdir()
    (root / "__init__.py").write_text("")
    (root / "main.py").write_text("from . import helper\n")
    (root / "helper.py").write_text('SHADER = "shade.glsl"\n')
    (root / "shade.glsl").write_text("void main() {}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield root
    for name in [n for n in sys.modules if n.startswith("cached_technique_pkg")]:
        del sys.modules[name]


def test_a_second_call_parses_nothing(package, monkeypatch):
    """Catches the hash found again at every call (0.18 s a technique: half of each
    harness.run.evaluate on a small scene)."""
    first = code_version.code_hash("cached_technique_pkg.main")
    parsed = []
    real_parse = ast.parse
    monkeypatch.setattr(ast, "parse", lambda *a, **k: parsed.append(a) or real_parse(*a, **k))
    assert code_version.code_hash("cached_technique_pkg.main") == first
    assert parsed == []


@pytest.mark.parametrize("edited", ["helper.py", "shade.glsl"])
def test_an_edit_of_a_followed_file_changes_the_hash(package, edited):
    """The helper's source and the shader it names, each edited in place (one line appended)
    between two calls in one process. Catches a cache kept without looking at the files."""
    before = code_version.code_hash("cached_technique_pkg.main")
    assert {p.name for p in code_version.code_files("cached_technique_pkg.main")} == {
        "__init__.py", "main.py", "helper.py", "shade.glsl"}
    with (package / edited).open("a") as f:
        f.write("// an edit\n" if edited.endswith(".glsl") else "# an edit\n")
    assert code_version.code_hash("cached_technique_pkg.main") != before
