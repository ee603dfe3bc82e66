"""Work per ray, counted in an untimed repeat of the trace: nodes entered (both levels; an
internal node entered is a test of its two children's boxes) and triangle tests, each ray's
written by ``rt_trace.comp.glsl`` built with ``COUNT``, over all rays and over the occluded
ones (those that had to find a triangle: the traversal's depth)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from OpenGL import GL

from harness.gl.shaders import ComputeProgram


class RayCounter:
    """The counting trace for a mask of ``width`` x ``height`` (``defines``: the trace's)."""

    def __init__(self, width: int, height: int, defines: dict):
        self.width, self.height = width, height
        self.alpha_test = "ALPHA_TEST" in defines
        self.program = ComputeProgram(Path(__file__).parent / "rt_trace.comp.glsl",
                                      {**defines, "COUNT": 1})
        self.texture = GL.glGenTextures(1)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.texture)
        GL.glTexStorage2D(GL.GL_TEXTURE_2D, 1, GL.GL_RGBA32UI, width, height)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)

    def count(self, trace) -> dict:
        """Run ``trace(program)`` with the counting program (it writes the same mask) and
        return the per-ray means and 99th percentiles over the rays traced."""
        GL.glBindImageTexture(1, self.texture, 0, GL.GL_FALSE, 0, GL.GL_WRITE_ONLY, GL.GL_RGBA32UI)
        trace(self.program)
        GL.glMemoryBarrier(GL.GL_TEXTURE_UPDATE_BARRIER_BIT)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.texture)
        out = np.empty((self.height, self.width, 4), np.uint32)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        GL.glGetTexImage(GL.GL_TEXTURE_2D, 0, GL.GL_RGBA_INTEGER, GL.GL_UNSIGNED_INT, out)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        rays = out[..., 0] > 0  # every traced ray visits the top level's root
        nodes, tests, occluded, alpha_tests = (out[..., i][rays] for i in range(4))
        counted = per_ray(nodes, tests, occluded.astype(bool))
        if self.alpha_test and len(alpha_tests):
            counted["alpha_tests_per_ray"] = round(float(alpha_tests.mean()), 3)
        return counted

    def release(self) -> None:
        self.program.release()
        GL.glDeleteTextures(1, [self.texture])


def per_ray(nodes: np.ndarray, tests: np.ndarray, occluded: np.ndarray) -> dict:
    """Mean and 99th percentile of nodes entered and triangle tests per ray, the mean nodes of
    an occluded ray, the rays, and the frame's totals."""
    if not len(nodes):
        return {"rays": 0}
    return {"rays": int(len(nodes)), "occluded_rays": int(occluded.sum()),
            # a frame's totals: the cost model's traversal work (harness.analysis.cost_model)
            "traversal_nodes": int(nodes.sum(dtype=np.int64)),
            "triangle_tests": int(tests.sum(dtype=np.int64)),
            "nodes_per_occluded_ray": (round(float(nodes[occluded].mean()), 3)
                                       if occluded.any() else None),
            "nodes_per_ray": round(float(nodes.mean()), 3),
            "nodes_per_ray_p99": float(np.percentile(nodes, 99)),
            "tests_per_ray": round(float(tests.mean()), 3),
            "tests_per_ray_p99": float(np.percentile(tests, 99))}
