"""The wheel, as a user installs it: built from this checkout (``pip wheel --no-deps``), installed
with ``--no-deps`` into a fresh virtual environment layered over this environment's
dependencies (mitsuba, pyrender, ... are not downloaded again; this project's own installation
is left out of the layer, so only the wheel's copy can answer), and run from an empty folder:
the shipped scenes are the default scene file, a shipped experiment runs by name and by its
repository path, and a run of box_plane scores sm."""

from __future__ import annotations

import csv
import os
import shutil
import site
import subprocess
import sys
from importlib.metadata import distribution
from pathlib import Path

import pytest
from helpers import ROOT

from harness.technique import registry

pytestmark = pytest.mark.slow

# what the wheel is built from (the sources setup.py and MANIFEST.in name)
SOURCES = ("harness", "techniques", "papers", "scenes.yaml", "experiments", "pyproject.toml",
           "setup.py", "MANIFEST.in", "README.md")

EXPERIMENT = """\
scenes: [box_plane]
techniques: {sm: {}}
resolutions: [[64, 64]]
frames: 1
warmup: 0
"""


def _own_files(site_dir: Path) -> set[str]:
    """The entries of ``site_dir`` that belong to this project's installed distribution (its
    dist-info, an editable install's finder and .pth, a wheel's packages)."""
    try:
        dist = distribution(registry.own_distribution())
    except Exception:  # not installed: a checkout on PYTHONPATH
        return set()
    if Path(dist.locate_file("")).resolve() != site_dir.resolve():
        return set()
    return {Path(f).parts[0] for f in dist.files or () if Path(f).parts[0] != ".."}


def _layer(work: Path) -> Path:
    """A folder of links to this environment's site-packages entries, less this project's."""
    layer = work / "deps"
    layer.mkdir()
    for folder in map(Path, site.getsitepackages()):
        own = _own_files(folder)
        for entry in folder.iterdir():
            if entry.name not in own and not (layer / entry.name).exists():
                (layer / entry.name).symlink_to(entry)
    return layer


def _run(venv: Path, *args: str, cwd: Path, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run([str(venv / "bin" / "shadowbench"), *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(the fresh environment's folder, a shell environment without this checkout on
    PYTHONPATH, an empty folder to run in)."""
    work = tmp_path_factory.mktemp("wheel")
    source = work / "source"  # a copy: a build writes build/ and egg-info beside its sources
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        else:
            shutil.copy2(ROOT / name, source / name)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w",
                            str(work / "dist"), str(source)],
                           env=env, capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stderr[-3000:]
    wheel, = (work / "dist").glob("*.whl")
    assert wheel.name.startswith("hard_shadow_bench-"), wheel.name
    venv = work / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True,
                   timeout=120)
    purelib, = (venv / "lib").glob("python*/site-packages")
    (purelib / "zz_project_deps.pth").write_text(
        f"import site; site.addsitedir({str(_layer(work))!r})\n")
    install = subprocess.run([sys.executable, "-m", "pip", "--python", str(venv / "bin" / "python"),
                              "install", "-q", "--no-deps", "--no-index", str(wheel)],
                             env=env, capture_output=True, text=True, timeout=300)
    assert install.returncode == 0, install.stderr[-3000:]
    elsewhere = work / "elsewhere"
    elsewhere.mkdir()
    return venv, env, elsewhere


def test_the_wheel_runs_a_shipped_scene_from_another_folder(installed):
    """Catches the wheel without scenes.yaml or experiments/ (``list``: no scene file; ``run``
    of box_plane: no scene file, exit 2), without the shaders or the report's templates, and
    the built-ins taken for a plugin under the new distribution name."""
    venv, env, elsewhere = installed
    where = subprocess.run([str(venv / "bin" / "python"), "-c",
                            "import harness; print(harness.__file__)"],
                           cwd=elsewhere, env=env, capture_output=True, text=True, timeout=120)
    assert where.stdout.startswith(str(venv)), (where.stdout, where.stderr)

    listed = _run(venv, "list", cwd=elsewhere, env=env)
    assert listed.returncode == 0, listed.stderr
    shipped = Path(where.stdout.strip()).parent / "shipped"
    assert f"scenes (from {shipped / 'scenes.yaml'}):" in listed.stdout, listed.stdout[-2000:]
    assert "box_plane" in listed.stdout and "BROKEN" not in listed.stdout
    assert "plugin:" not in listed.stdout  # the wheel's techniques are the built-ins
    assert "default, hard_cases" in listed.stdout

    # a shipped experiment by name and by its path in the repository: its own scene file
    # and the meshes beside it come from the wheel
    for name in ("hard_cases", "experiments/hard_cases.yaml"):
        plan = _run(venv, "plan", name, "--techniques", "sm", cwd=elsewhere, env=env)
        assert plan.returncode == 0, plan.stderr
        assert "hard_degenerate_open_meshes" in plan.stdout, plan.stdout
    missing = _run(venv, "plan", "no_such_experiment", cwd=elsewhere, env=env)
    assert missing.returncode == 2
    assert missing.stderr.startswith("shadowbench: experiment no_such_experiment: no such file")

    (elsewhere / "small.yaml").write_text(EXPERIMENT)
    run = _run(venv, "run", "small.yaml", "--out", "out", "--report", "--quiet",
               cwd=elsewhere, env=env)
    assert run.returncode == 0, run.stderr
    with (elsewhere / "out" / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [(r["scene"], r["technique"], r["status"]) for r in rows] == [("box_plane", "sm", "ok")]
    assert 0 < float(rows[0]["mae"]) < 0.05
    assert (elsewhere / "out" / "index.html").is_file()
    assert sorted(p.name for p in elsewhere.iterdir()) == ["out", "small.yaml"]
