"""The Python API, beside the command line: one technique on one scene, planned, measured and
scored in this process with nothing stored (for tests and notebooks)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..technique import registry
from ..scene import BuiltScene, load_scene
from .measure import run_one
from .plan import RunSpec, validate_params


@dataclass
class Evaluation:
    row: dict
    visibility: np.ndarray | None
    reference: object  # harness.truth.reference.Reference
    frame_arrays: object  # harness.gl.gbuffer.GBufferArrays
    mask: np.ndarray  # the pixels every metric compares (Frame.compared_pixels)
    arrays: dict | None = None  # what the run stores (a moving scene's series among them)


def evaluate(scene: BuiltScene | str, technique: str, params: dict | None = None, *,
             scene_file: str | Path = "scenes.yaml", resolution: tuple[int, int] | None = None,
             frames: int = 1, warmup: int = 0, samples: int = 16,
             cost: str = "dynamic") -> Evaluation:
    """Run one technique on one scene in this process and score it (for tests, notebooks).

    ``scene`` is a built scene or the name of one in ``scene_file``; ``resolution`` (width,
    height) replaces the scene's own; ``cost`` is the cost policy (dynamic or static,
    :mod:`harness.run.measure`). The reference comes from the on-disk cache when present.
    A moving scene runs its whole sequence (``frames`` is then its length); ``visibility``,
    ``reference``, ``frame_arrays`` and ``mask`` are frame 0's.
    """
    from ..gl.context import get_context
    from ..truth.reference import compute_reference
    from ..technique import Frame

    if isinstance(scene, str):
        scene = load_scene(scene, scene_file)
    if resolution is not None:
        scene = scene.with_resolution(*resolution)
    context = get_context()
    cls = registry.get(technique)
    checked = validate_params(technique, params or {}, "evaluate()")
    spec = RunSpec(scene.name, technique, checked, scene.width, scene.height,
                   scene.frames if scene.frames > 1 else frames, warmup, samples, 0, scene.key,
                   cls.code_version(), cost=cost)
    reference = compute_reference(scene.at_frame(0), samples=samples)
    frame = Frame(scene)
    try:
        scene_ms, frags_scene = frame.measure_scene_pass(frames, warmup)
        row, arrays = run_one(spec, frame, reference, scene_ms, frags_scene, context.renderer)
        return Evaluation(row, arrays["visibility"] if arrays else None, reference, frame.arrays,
                          frame.compared_pixels(reference.covered), arrays)
    finally:
        frame.release()
