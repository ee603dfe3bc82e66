"""What a technique's ``code_version`` hashes: its module, the modules of the technique's own
packages that it imports (following imports, relative or absolute), and the .glsl files any of
them names (following ``#include``, into shared packages and the harness's own shaders).

A file counts when it lies inside a technique root: the top-level package of the technique's
module or of any registered technique (so a plugin that reuses ``techniques.common`` hashes the
shared code it runs). Library code (numpy, the harness's Python) is outside every root. A
class's colour declaration (``colour = "#rrggbb"``, :mod:`harness.technique.colour`) is left
out: it changes no result.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import re
import sys
from importlib.metadata import entry_points
from pathlib import Path

from ..gl.shaders import HARNESS_GLSL
from ..machine.file_stamps import stamps

GROUP = "shadowbench.techniques"  # the entry-point group techniques register in
_GLSL_NAME = re.compile(r"[\w./]+\.glsl")


def code_hash(module_name: str) -> str:
    """The 12-hex-digit hash of the code reached from ``module_name`` (see the module).

    Kept for the process while none of the files it read changed (their modification time,
    size and inode): finding them parses every module reached, 0.18 s a technique, which
    ``harness.run.evaluate`` and ``plan`` paid at every call."""
    from .colour import strip_declaration

    key = (module_name, _source(module_name))
    known = _hashes.get(key)
    if known is not None and stamps(known[0]) == known[1]:
        return known[2]
    files = code_files(module_name)
    read = stamps(files)
    digest = hashlib.sha256(b"".join(p.name.encode() + strip_declaration(p.read_bytes())
                                     for p in files)).hexdigest()[:12]
    if read is not None:
        _hashes[key] = (files, read, digest)
    return digest


# (module, its file) -> (the files code_hash read, their stamps taken before hashing, the hash)
_hashes: dict[tuple, tuple[list[Path], tuple, str]] = {}


def code_files(module_name: str) -> list[Path]:
    """The files ``code_hash`` reads for ``module_name``, sorted."""
    roots = _technique_roots(module_name)
    seen: set[Path] = set()
    modules, shaders = [module_name], []
    while modules or shaders:
        if modules:
            name = modules.pop()
            path = _source(name)
            if path is None or path in seen or not any(path.is_relative_to(r) for r in roots):
                continue
            seen.add(path)
            text = path.read_text()
            modules.extend(_imported_modules(text, name, path))
        else:
            path = shaders.pop()
            if path in seen or not path.is_file():
                continue
            seen.add(path)
            text = path.read_text()
        shaders.extend(_glsl_path(n, path.parent) for n in _GLSL_NAME.findall(text))
    return sorted(seen)


def _source(module_name: str) -> Path | None:
    module = sys.modules.get(module_name)
    origin = getattr(module, "__file__", None)
    if origin is None:
        try:
            spec = importlib.util.find_spec(module_name)
        except (ImportError, ValueError):  # a class or function imported by name
            return None
        origin = spec.origin if spec else None
    return Path(origin).resolve() if origin and origin.endswith(".py") else None


def _imported_modules(text: str, module_name: str, path: Path) -> list[str]:
    """Every module an import statement of ``text`` may name: ``from a.b import c`` gives
    ``a.b`` and ``a.b.c`` (c may be a submodule); relative imports are resolved."""
    package = module_name if path.name == "__init__.py" else module_name.rpartition(".")[0]
    names = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = ("." * node.level + (node.module or "")) if node.level else node.module
            try:
                base = importlib.util.resolve_name(base, package) if node.level else base
            except ImportError:
                continue
            names += [base] + [f"{base}.{alias.name}" for alias in node.names]
    return names


def _glsl_path(name: str, folder: Path) -> Path:
    here = (folder / name).resolve()
    return here if here.is_file() else (HARNESS_GLSL / name).resolve()


def _technique_roots(module_name: str) -> list[Path]:
    tops = {module_name.partition(".")[0]}
    tops |= {ep.value.partition(".")[0].partition(":")[0] for ep in entry_points(group=GROUP)}
    roots = []
    for top in sorted(tops):
        try:
            spec = importlib.util.find_spec(top)
        except (ImportError, ValueError):
            continue
        if spec is None:
            continue
        # a package's folders; a top-level module is its own root (never its site-packages)
        locations = spec.submodule_search_locations or ([spec.origin] if spec.origin else [])
        roots += [Path(loc).resolve() for loc in locations]
    return roots
