"""Fixtures of the technique tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def frames(gl_context, request):
    """``frames(path, name, size=RES)``: a Frame of scene ``name`` of the scene file ``path`` at
    ``size`` x ``size`` (the test module's ``RES``), made once per module and released after."""
    from harness.scene import load_scene
    from harness.technique import Frame

    made = {}

    def frame(path, name, size=None):
        size = size or request.module.RES
        if (path, name, size) not in made:
            made[(path, name, size)] = Frame(load_scene(name, path).with_resolution(size, size))
        return made[(path, name, size)]

    yield frame
    for f in made.values():
        f.release()
