"""Ray-traced hard shadows: one any-hit shadow ray per G-buffer pixel through a two-level BVH."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from OpenGL import GL
from pydantic import Field

from harness.gl.framebuffer import Texture
from harness.gl.shaders import ComputeProgram
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams
from techniques.common.mask import mask_visibility_program

from . import bvh, counters, levels
from .embree import EmbreeRays

MASK_DIVISOR = {"full": 1, "half": 2, "quarter": 4}
GROUP = 16  # rt_trace.comp.glsl's local size along each axis: 16x16 took 10-20% less than
# 8x8 and 4x2 was much slower (castle and architecture@1e5 at 512^2, two rounds each, noisy)


class RayTraced(Technique):
    """Exact hard shadows the way engines without volumes get them: from each covered G-buffer
    pixel's world position (the pixel centre, point-sampled as sv's), one shadow ray towards the
    light (directional, spot or point), any hit ending it, so V is 0 or 1.

    The rays run through a two-level BVH (``levels``): a bottom level per part, built once in
    ``prepare`` from the part's triangles (``build``: ``lbvh``, Karras 2012's Morton split, or
    ``sah``, binned surface-area heuristic; ``bvh``), and a top level over the parts' instances
    at their poses (``Frame.part_poses``), rebuilt in ``update`` inside the timed ``tlas`` pass
    (every frame under ``cost: dynamic``). ``backend: gl`` traverses in a compute shader
    (``rt_trace.comp.glsl``: Aila and Laine 2009's stack traversal, each internal node holding
    both children's boxes, nearer child first, over buffer textures; Woop,
    Benthin and Wald 2013's watertight triangle test) in the timed ``trace`` pass;
    ``backend: embree`` traces the same rays on the CPU with Mitsuba's ``ray_test``
    (``embree``), its G-buffer read-back, trace and V upload in timed passes, moving objects'
    parts as Mitsuba instances moved in the timed ``tlas`` pass. Alpha-tested casters: a hit
    on a cut-out texel does not end the ray (``alpha_test.glsl``'s rule at the hit's texture
    coordinates in the traversal; on the embree backend a loop that goes on past it), and
    each ray's alpha tests are counted (``alpha_tests_per_ray``, four texels each in
    ``fetches_per_px``).

    A pixel whose visible side faces away from the light gets V = 0 and no ray (it receives
    no light; such pixels are never compared). The origin of each ray is the G-buffer point
    moved off its surface along that normal, by 256 units in the last place of each
    coordinate (Waechter and Binder 2019; ``common/ray_offset.glsl`` says why): the offset follows the
    position's own rounding, whatever the scene's scale. ``mask_res: half`` or ``quarter``
    traces one ray per 2x2 or 4x4 pixels and magnifies the 0/1 mask bilinearly, as sv's
    smaller masks. One-off work (the bottom levels, Mitsuba's scene) is the harness's
    ``prepare_ms``. Nodes entered and triangle tests per ray are counted in an untimed repeat
    of the trace (``counters``); ``mem_bytes`` is the BVH's bytes and the mask's.

    ==================  ==================================================  =======  ==========
    Parameter           Meaning                                             Default  Range
    ==================  ==================================================  =======  ==========
    ``backend``         ``gl`` (compute shader) or ``embree`` (Mitsuba's    gl
                        CPU ``ray_test``)
    ``build``           bottom-level builder: ``lbvh`` or ``sah``           lbvh
    ``leaf_size``       most triangles in a bottom-level leaf               4        1 .. 16
    ``mask_res``        ``full``, ``half`` or ``quarter`` (one ray per      full
                        1, 2x2, 4x4 pixels; bilinear magnification)
    ``budget_mib``      refuse a scene whose bottom levels could take       256      1 .. 4096
                        more MiB (bound: one triangle per leaf), before
                        building
    ==================  ==================================================  =======  ==========
    """

    name = "rt"
    colour = "#7f7f7f"
    summary = "ray-traced shadows: one any-hit ray per pixel through a two-level BVH"
    paper = ("Whitted 1980, An improved illumination model for shaded display; Aila, Laine 2009, "
             "Understanding the efficiency of ray traversal on GPUs; Karras 2012, Maximizing "
             "parallelism in the construction of BVHs")
    # quality knob: rays per pixel (the one way a point-sampled exact method buys time)
    quality_knobs = {"mask_res": ("quarter", "half", "full")}
    declines_lights = {}  # a ray reaches a point light as a spot light
    alpha_casters = True  # any-hit: a hit on a cut-out texel does not end the ray
    rivals = ("sv", "silhouette")  # the exact volumes and the map with exact edges

    class Params(TechniqueParams):
        backend: Literal["gl", "embree"] = "gl"
        build: Literal[tuple(bvh.BUILDERS)] = "lbvh"
        leaf_size: int = Field(4, ge=1, le=16)
        mask_res: Literal["full", "half", "quarter"] = "full"
        budget_mib: int = Field(256, ge=1, le=4096)

    @classmethod
    def check_scene(cls, params, scene) -> None:
        triangles = sum(len(part.faces) for part in scene.parts)
        bound = levels.bound_bytes(triangles, scene.has_alpha)
        if bound > params.budget_mib * 2**20:
            raise ValueError(f"budget_mib: {triangles:,} triangles could take "
                             f"{bound / 2**20:.0f} MiB of BVH, over the budget of "
                             f"{params.budget_mib} MiB")

    def prepare(self, frame: Frame) -> None:
        p = self.params
        self.check_scene(p, frame.scene)  # refused before anything is built
        parts = frame.scene.parts
        divisor = MASK_DIVISOR[p.mask_res]
        self.mask = Texture(-(-frame.width // divisor), -(-frame.height // divisor), GL.GL_R32F)
        self.divisor = divisor
        self.visibility_program = mask_visibility_program(divisor)
        self.levels = self.embree = self.trace_program = None
        self.counted = (None, {})  # what the counters were last counted for, and their values
        if p.backend == "embree":
            self.embree = EmbreeRays(frame)
            return
        masks = frame.scene.alpha_masks
        self.levels = levels.TwoLevelBvh(parts, p.build, p.leaf_size, masks)
        defines = {"STACK_SIZE": self.levels.stack_size, **({"ALPHA_TEST": 1} if masks else {})}
        self.trace_program = ComputeProgram(Path(__file__).parent / "rt_trace.comp.glsl", defines)
        self.counter = counters.RayCounter(self.mask.width, self.mask.height, defines)

    def update(self, frame: Frame) -> None:
        if self.embree is not None:
            self.embree.follow(frame)
            return
        with frame.measure("tlas"):
            self.levels.rebuild_top(frame.part_poses)

    def _light_uniforms(self, frame: Frame) -> dict:
        light = frame.scene.light
        if light.type == "directional":
            return dict(directional=True, light=-np.asarray(light.direction, np.float64))
        return dict(directional=False, light=np.asarray(light.position, np.float64))

    def _trace(self, frame: Frame, program) -> None:
        if self.levels.empty:
            self.mask.clear(1.0)
            return
        program.use()
        unit = frame.bind_gbuffer(program)
        frame.bind_alpha(program, self.levels.bind(program, unit))
        program.set(divisor=self.divisor, camera_position=frame.camera.position,
                    **self._light_uniforms(frame))
        GL.glBindImageTexture(0, self.mask.id, 0, GL.GL_FALSE, 0, GL.GL_WRITE_ONLY, GL.GL_R32F)
        GL.glDispatchCompute(-(-self.mask.width // GROUP), -(-self.mask.height // GROUP), 1)
        GL.glMemoryBarrier(GL.GL_TEXTURE_FETCH_BARRIER_BIT | GL.GL_SHADER_IMAGE_ACCESS_BARRIER_BIT)
        # unbound at once, as harness.gl.reduction does: Mesa (llvmpipe) otherwise keeps the
        # program bound after a dispatch alive past its deletion (a leak the contract test saw)
        GL.glUseProgram(0)

    def _visibility_pass(self, frame: Frame) -> None:
        frame.begin_visibility()
        program = self.visibility_program.use()
        unit = frame.bind_gbuffer(program)
        program.set(shadow_mask=self.mask.bind(unit), mask_channel=0, lit_threshold=0.5)
        frame.draw_fullscreen(covered_only=True)

    def _count(self, frame: Frame) -> dict:
        """The rays' work, counted untimed by the same rays again, whenever the light, the
        camera or an object moved (once on a still scene): a diagnostic, as sv's fill."""
        light = frame.scene.light
        key = tuple(b"" if v is None else np.asarray(v).tobytes()
                    for v in (light.direction, light.position, frame.camera.view_proj,
                              frame.part_poses))
        if key != self.counted[0] and not self.levels.empty:
            self.counted = (key, self.counter.count(lambda program: self._trace(frame, program)))
        return dict(self.counted[1])

    def render(self, frame: Frame) -> ShadowOutput:
        extra = {}
        if self.embree is not None:
            extra = self.embree.trace(frame, self.mask, self.divisor,
                                      self._light_uniforms(frame), frame.camera.position)
            bvh_bytes = 0
        else:
            with frame.measure("trace"):
                self._trace(frame, self.trace_program)
            bvh_bytes = self.levels.nbytes
            extra = self._count(frame)
        with frame.measure("visibility"):
            self._visibility_pass(frame)
        extra["bvh_bytes"] = bvh_bytes
        # the mask's reads, and per ray each alpha test's four texels
        alpha_fetches = 4 * extra.get("alpha_tests_per_ray", 0.0) / self.divisor ** 2
        return frame.output(mem_bytes=bvh_bytes + self.mask.nbytes,
                            fetches_per_px=(1 if self.divisor == 1 else 4) + alpha_fetches,
                            extra=extra)

    def release(self) -> None:
        for resource in (self.trace_program, getattr(self, "counter", None), self.mask,
                         self.visibility_program, self.levels, self.embree):
            if resource is not None:
                resource.release()
