"""Shared fixtures: one GL context per test process, the shipped scenes at test resolutions."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from helpers import ROOT, SCENE_FILE

os.environ.setdefault("SHADOWBENCH_CACHE", str(ROOT / ".cache" / "shadowbench"))
# The commands tests start (python -m harness.cli, from any folder) run this checkout's code,
# not whichever checkout the environment's editable install points at (a git worktree's tests
# would otherwise exercise another tree).
os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)


@pytest.fixture(scope="session")
def gl_context():
    from harness.gl.context import get_context

    return get_context()


@pytest.fixture(scope="session")
def shipped_scenes():
    from harness import config

    return config.load_scenes(SCENE_FILE)


@pytest.fixture(scope="session")
def scene_at(shipped_scenes):
    """``scene_at(name, width, height=width)``: a shipped scene built at that resolution."""
    from harness.scene import build_scene

    cache = {}

    def make(name: str, width: int, height: int | None = None):
        key = (name, width, height or width)
        if key not in cache:
            base = build_scene(name, shipped_scenes[name], SCENE_FILE)
            cache[key] = base.with_resolution(width, height or width)
        return cache[key]

    return make


@pytest.fixture(scope="session")
def evaluate(gl_context):
    """``evaluate(scene, technique, params=None, **kw)`` -> harness.run.Evaluation."""
    from harness.run import evaluate as run

    return run


@pytest.fixture
def small_scene_file(tmp_path, shipped_scenes):
    """``small_scene_file(*names, size=(64, 48))``: a scene file of shipped scenes made small."""
    import yaml

    def write(*names, size=(64, 48)):
        scenes = {}
        for name in names or ("box_plane", "sphere_plane"):
            scene = shipped_scenes[name].model_dump(mode="json")
            scene["resolution"] = list(size)
            scenes[name] = scene
        path = tmp_path / "small_scenes.yaml"
        path.write_text(yaml.safe_dump({"scenes": scenes}))
        return path

    return write


@pytest.fixture
def make_results():
    """``make_results(folder, runs, scene="s", size=32)``: a results folder written by hand (no
    GL): a reference with a square shadow, and per run a row and arrays. Each run is a dict of
    row values over sm at its defaults (``shift``: V is the reference moved right by that many
    pixels, so its error sits on the shadow's vertical edges)."""
    import json

    import numpy as np

    from harness.truth import metrics
    from harness.technique import registry
    from harness import results

    def write(folder, runs, scene="s", size=32):
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        ref = np.ones((size, size), np.float32)
        ref[size // 4:3 * size // 4, size // 4:3 * size // 4] = 0.0
        covered = np.ones((size, size), bool)
        reference = f"arrays/ref-{size}.npz"
        results.save_arrays(folder / reference, visibility=ref, covered=covered)
        sm = registry.get("sm")
        rows = []
        for i, run in enumerate(runs):
            run = dict(run)
            v = np.roll(ref, run.pop("shift", 0), axis=1)
            params = {**sm.Params().model_dump(mode="json"), **run.pop("params", {})}
            array = f"arrays/run-{i}.npz"
            results.save_arrays(folder / array, visibility=v, covered=covered)
            rows.append({
                "run_id": f"{i:016d}", "schema": results.SCHEMA_VERSION, "scene": scene,
                "technique": "sm", "params": json.dumps(params, sort_keys=True),
                "width": size, "height": size, "time_ms": 1.0, "scene_ms": 0.5,
                "mae": metrics.mae(v, ref), "wrong_pct": metrics.wrong_pct(v, ref),
                "edge_mae": metrics.edge_mae(v, ref), "status": "ok", "error": "",
                "code_version": sm.code_version(), "array": array,
                "reference_array": reference, "v_min": 0.0, "v_max": 1.0, "nonfinite": 0,
                **run})
        results.write_rows(folder, rows)
        return folder

    return write


@pytest.fixture(scope="session")
def plugin_env(tmp_path_factory):
    """``plugin_env(*sources)``: the environment of a shell in which the plugin distributions
    at ``sources`` (folders with a pyproject.toml) are installed: each built offline from a copy
    (a build writes beside its sources; the repository stays as it was) into one folder put
    first on PYTHONPATH.

    setuptools builds them, with its own build_py and egg_info rather than through pip: the
    setuptools of Python 3.11's venv (65.5) builds a wheel only with the separate ``wheel``
    package, which is not installed, and pip has no other way to build offline. The installed
    files are the same, and importlib.metadata reads the egg-info's entry_points.txt as it
    reads a wheel's dist-info."""
    import shutil
    import subprocess
    import sys

    pytest.importorskip("setuptools")

    def install(*sources: Path) -> dict:
        work = tmp_path_factory.mktemp("plugins")
        site = work / "site"
        for source in sources:
            copy = work / Path(source).name
            shutil.copytree(source, copy)
            build = subprocess.run([sys.executable, "-c", "from setuptools import setup; setup()",
                                    "-q", "build_py", "--build-lib", str(site),
                                    "egg_info", "--egg-base", str(site)],
                                   cwd=copy, capture_output=True, text=True, timeout=120)
            assert build.returncode == 0, build.stderr
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(site), env.get("PYTHONPATH")]))
        return env

    return install


@pytest.fixture(scope="session")
def small_run_dir(tmp_path_factory, gl_context):
    """``small_run_dir(copy_to)``: helpers.make_run_dir's folder (a real sweep: every technique
    on two scenes, about 13 s), swept once for the whole session, the test workers included
    (the first to ask sweeps it under a lock in the folder they share), and copied to
    ``copy_to`` for each module that asks: each builds its own dashboard in its copy."""
    import fcntl
    import shutil

    from helpers import make_run_dir

    shared = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        shared = shared.parent  # the session's folder, which pytest-xdist's workers share
    source = shared / "small-run" / "run"
    with open(shared / "small-run.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (source.parent / "done").exists():
            shutil.rmtree(source.parent, ignore_errors=True)
            source.parent.mkdir()
            make_run_dir(source)
            (source.parent / "done").touch()

    def copy(to: Path) -> Path:
        shutil.copytree(source, to)
        return to

    return copy
