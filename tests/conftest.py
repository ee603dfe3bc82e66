"""Shared fixtures: one GL context per test process, the shipped scenes at test resolutions."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCENE_FILE = ROOT / "scenes.yaml"

os.environ.setdefault("SHADOWBENCH_CACHE", str(ROOT / ".cache" / "shadowbench"))


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
    """``evaluate(scene, technique, params=None, **kw)`` -> harness.runner.Evaluation."""
    from harness.runner import evaluate as run

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
