"""The irregular z-buffer: frustum-traced raster shadows (Johnson et al. 2005; Wyman,
Hoetzlein, Lefohn 2015, 2016)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from OpenGL import GL
from pydantic import Field, ValidationInfo, field_validator

from harness.config import power_of_two
from harness.gl.gbuffer import GBuffer
from harness.gl.shaders import ComputeProgram, Program
from harness.scene.transforms import fit_light
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams

from . import patterns
from .storage import EmptyTarget, IntegerImage, StorageBuffer

HERE = Path(__file__).parent
SAMPLE_COUNTS = (1, 4, 8, 16, 32)
REFERENCE_COUNTS = (1, 4, 16)  # the reference's stratified grid is square
MAX_RES = 8192
# bytes per sample slot: its world position (vec4) and its list's next pointer; a reference
# pattern adds its offset (vec2)
SLOT_BYTES = 16 + 4
OFFSET_BYTES = 8
GBUFFER_BYTES = 16 + 16 + 4  # surface: raster's own G-buffer, per pixel: position, normal, depth
END = 0  # the end of a list (a link is a slot + 1)
# llvmpipe ends a shader invocation's loops after this many iterations in all (gallivm's loop
# limiter, one count per invocation, nested loops included): a caster fragment tests at most
# this many samples of its texel's list, and a longer list's tail stays lit
LOOP_LIMIT = 65535
GROUP = 16  # izb_samples.comp.glsl's local size along each axis
LIST_GROUP = 256  # izb_lists.comp.glsl's


def bound_bytes(width: int, height: int, params) -> int:
    """The lists' memory: every pixel's sample slots and masks (and with ``surface: raster``
    its missed samples and the G-buffer they are read from), the grid's head pointers."""
    slot = SLOT_BYTES + (OFFSET_BYTES if params.pattern == "reference" else 0)
    pixel = params.samples * slot + 4 + (4 + GBUFFER_BYTES if params.surface == "raster" else 0)
    return width * height * pixel + params.res * params.res * 4


def jitter(offset, width: int, height: int) -> np.ndarray:
    """The clip-space translation that moves a camera's image by ``offset`` pixels (x right,
    y up), so each pixel's centre sees the film point ``offset`` from its own."""
    move = np.eye(4)
    move[0, 3], move[1, 3] = -2 * offset[0] / width, -2 * offset[1] / height
    return move


def ordered(values) -> np.ndarray:
    """Floats as izb_grid.glsl's order-preserving unsigned integers."""
    bits = np.asarray(values, np.float32).view(np.uint32)
    return np.where(bits & 0x80000000, ~bits, bits | 0x80000000).astype(np.uint32)


PLAIN_BOUNDS = ordered([-1, -1, 1, 1])  # fit: plain, the light frustum's whole square
EMPTY_BOUNDS = ordered([np.inf, np.inf, -np.inf, -np.inf])  # fit: view, before the samples


def list_statistics(lengths: np.ndarray) -> dict:
    """Mean, 99th percentile and maximum of the lengths of the grid's non-empty lists, and the
    lists longer than LOOP_LIMIT."""
    filled = lengths[lengths > 0]
    if not len(filled):
        return {"list_mean": 0.0, "list_p99": 0.0, "list_max": 0, "lists_over_limit": 0}
    return {"list_mean": round(float(filled.mean()), 3),
            "list_p99": float(np.percentile(filled, 99)), "list_max": int(filled.max()),
            "lists_over_limit": int((filled > LOOP_LIMIT).sum())}


def caster_program(defines: dict) -> Program:
    """The conservative caster raster with its sample tests (``defines``: SAMPLES, ALPHA_TEST
    on a scene with alpha-tested casters, and COUNT or TEXEL_FRAGMENTS for the counting
    ones)."""
    return Program(HERE / "izb_casters.vert.glsl", HERE / "izb_casters.frag.glsl", defines,
                   geometry=HERE / "izb_casters.geom.glsl")


class IrregularZBuffer(Technique):
    """Exact hard shadows by rasterisation: the view's samples are linked into per-texel lists
    of a light-space grid, then every caster is rasterised conservatively into that grid and
    each fragment tests its triangle against the samples of its texel.

    **Samples** (``izb_samples.comp.glsl``, timed ``samples``): each covered G-buffer pixel
    has ``samples`` view samples, at the sub-pixel offsets of ``pattern`` (``patterns``).
    ``surface: raster`` (the default) finds each sample exactly where its camera ray meets the
    scene: the camera pass is rendered again per sample offset, the camera moved by it (a
    multisampled G-buffer, one offset a pass; the centre offset reuses the frame's pass), so a
    pixel's samples may land on different surfaces, and V is the lit fraction of those whose
    ray meets one, as the reference counts its samples. ``surface: plane`` places them as
    Wyman et al. do, where the ray meets the pixel's surface plane (the G-buffer point and its
    normal), with no extra pass: where a pixel's samples would fall on different surfaces (a
    silhouette, a crease) they all stay on the centre's plane, extended; at concave creases of
    tessellated surfaces that plane runs under the neighbouring faces, which then shadow it
    (16 samples on the real corpus at 128 x 128: acne 2.7 % on real_vault, edge_mae 1.3 to
    1.7 x edge_floor; raster: 0.28 x). One centred sample is the G-buffer point itself
    either way. Each sample is moved off its surface by ``common/ray_offset.glsl``, rt's ray
    origin; a sample whose visible side faces away from the light is shadowed and not
    inserted (as rt).
    **Lists** (``izb_lists.comp.glsl``, ``lists``): a ``res`` x ``res`` grid over the light
    frustum of ``fit_light`` (directional: orthographic over the scene; spot: the cone's
    square), or with ``fit: view`` over the rectangle of it the samples span (merged on the
    GPU by the samples pass, no read-back); each sample linked into its texel's list by an
    atomic exchange on a head-pointer image, next pointers in a buffer.
    **Casters** (``izb_casters.*.glsl``, ``casters``): every triangle of the scene, each
    rasterised conservatively by geometry-shader expansion (llvmpipe has no hardware
    conservative raster): its bounding box in texels, grown by half a texel and 1/32, as a
    quad, the texels its edges separate from it dropped in the fragment shader, so every texel
    the triangle touches gets a fragment. Each fragment walks its texel's list and tests each
    sample against the triangle's shadow frustum (``izb_frustum.glsl``: three edge planes and
    the triangle's plane, signs decided in double where float rounding could flip them); an
    occluded sample sets its bit in its pixel's mask by an atomic OR.
    **Visibility**: V = the fraction of a pixel's samples left lit. One sample: exact 0/1 as
    rt's; 16 or 32 estimate the pixel-area average the reference computes.

    **Cut-outs** (``alpha_casters``): on a scene with alpha-tested casters, a sample in a
    caster's frustum is tested once more where its ray to the light meets the triangle (the
    barycentric weights of that point, from the frustum's edge determinants, interpolate the
    corners' texture coordinates) by ``alpha_test.glsl``'s rule: a cut-out texel does not
    shadow it. Those alpha tests are counted (``alpha_tests``) and add four texels each to
    ``fetches_per_px``. Scenes without cut-outs build the caster shader without the test.
    ``surface: raster``'s camera passes are the harness's G-buffer pass, so its samples see
    the surfaces the frame's G-buffer sees.

    Point lights are declined (one grid covers one frustum). llvmpipe ends an invocation's
    loops after 65535 iterations in all, so a
    fragment tests at most that many samples of its list: where the light sees many samples in
    one texel (terrain_long's far field: 185,299 at 512 x 512 with 16 samples and res 512) the
    tail is left lit; such lists are counted (``lists_over_limit``) and the run warns. List
    lengths (mean, p99, max over non-empty texels), samples inserted, caster fragments and
    sample tests are counted in an untimed repeat of the lists and casters passes
    (``extra``). ``mem_bytes``: sample slots, masks and head pointers, the
    bound ``budget_mib`` is checked against at plan time.

    ===============  ====================================================  =======  ==============
    Parameter        Meaning                                               Default  Range
    ===============  ====================================================  =======  ==============
    ``samples``      view samples per pixel                                1        1, 4, 8, 16, 32
    ``surface``      ``raster`` (each sample where its camera ray meets    raster
                     the scene: a camera pass per offset) or ``plane``
                     (on the pixel's surface plane, the paper's way)
    ``pattern``      ``rotated`` (one fixed sub-pixel pattern) or          rotated
                     ``reference`` (the reference's own positions per
                     pixel; samples 1, 4 or 16; surface plane)
    ``res``          the grid's width and height, texels (a power of       512      16 .. 8192
                     two)
    ``fit``          ``plain`` (the light frustum) or ``view`` (the        view
                     rectangle of it the view's samples span)
    ``budget_mib``   refuse a run whose lists could take more MiB          256      1 .. 4096
                     (every pixel's sample slots, masks, head pointers),
                     before anything is allocated
    ===============  ====================================================  =======  ==============
    """

    name = "izb"
    colour = "#b15928"
    summary = "irregular z-buffer: view samples in light-space lists, casters rasterised " \
              "conservatively and tested exactly"
    paper = ("Johnson, Lee, Burns, Mark 2005, The irregular z-buffer; Wyman, Hoetzlein, Lefohn "
             "2015, Frustum-traced raster shadows: revisiting irregular z-buffers")
    # quality knob: samples per pixel, the sub-pixel curve from rt's exact 0/1 towards the
    # reference's pixel-area average
    quality_knobs = {"samples": (1, 4, 16)}
    declines_lights = {"point": "one grid covers one light frustum (six faces are not built)"}
    rivals = ("rt", "sv")  # the exact rays and volumes
    alpha_casters = True  # a sample behind a cut-out texel of a caster stays lit

    class Params(TechniqueParams):
        samples: Literal[SAMPLE_COUNTS] = 1
        surface: Literal["raster", "plane"] = "raster"
        pattern: Literal["rotated", "reference"] = "rotated"
        res: int = Field(512, ge=16, le=MAX_RES)
        fit: Literal["plain", "view"] = "view"
        budget_mib: int = Field(256, ge=1, le=4096)

        _res = field_validator("res")(power_of_two)

        @field_validator("pattern")
        @classmethod
        def _reference_counts(cls, value: str, info: ValidationInfo) -> str:
            samples = info.data.get("samples")
            if value == "reference" and samples not in REFERENCE_COUNTS:
                raise ValueError(f"reference needs samples 1, 4 or 16 (the reference's "
                                 f"stratified grid is square), got samples {samples}")
            if value == "reference" and info.data.get("surface") == "raster":
                raise ValueError("reference needs surface: plane (raster renders one camera "
                                 "pass per sample offset, the same for every pixel)")
            return value

    @classmethod
    def check_scene(cls, params, scene) -> None:
        bound = bound_bytes(scene.width, scene.height, params)
        if bound > params.budget_mib * 2**20:
            raise ValueError(f"budget_mib: {scene.width}x{scene.height} pixels at "
                             f"{params.samples} samples and a {params.res}^2 grid take "
                             f"{bound / 2**20:.0f} MiB of lists, over the budget of "
                             f"{params.budget_mib} MiB")

    def prepare(self, frame: Frame) -> None:
        p = self.params
        self.check_scene(p, frame.scene)  # refused before anything is allocated
        self.slots = frame.width * frame.height * p.samples
        self.positions = StorageBuffer(16 * self.slots)
        self.next = StorageBuffer(4 * self.slots)
        self.masks = StorageBuffer(4 * frame.width * frame.height)
        self.bounds = StorageBuffer(16)
        self.heads = IntegerImage(p.res)
        self.target = EmptyTarget(p.res)
        self.offsets = self.missed = self.jittered = None
        defines = {"SAMPLES": p.samples}
        if p.surface == "raster":
            defines["RASTER_SURFACE"] = 1
            self.missed = StorageBuffer(4 * frame.width * frame.height)
            self.jittered = GBuffer(frame.width, frame.height, frame.alpha)
        if p.pattern == "reference":
            defines["REFERENCE_PATTERN"] = 1
            self.offsets = StorageBuffer(OFFSET_BYTES * self.slots)
            self.offsets.write(patterns.reference(frame.scene, p.samples))
        if p.fit == "view":
            defines["FIT_VIEW"] = 1
        self.pattern = patterns.rotated(p.samples)
        self.samples_program = ComputeProgram(HERE / "izb_samples.comp.glsl", defines)
        self.list_programs = [ComputeProgram(HERE / "izb_lists.comp.glsl", {**defines, **more})
                              for more in ({}, {"COUNT": 1})]
        cutouts = {"ALPHA_TEST": 1} if frame.scene.has_alpha else {}
        self.caster_programs = [caster_program({**defines, **cutouts, **more})
                                for more in ({}, {"COUNT": 1})]
        self.visibility_program = Technique.shader(__file__, "fullscreen.vert.glsl",
                                                   "izb_visibility.frag.glsl", **defines)
        self.counted = (None, {})

    def _light(self, frame: Frame) -> np.ndarray:
        light = frame.scene.light
        if light.type == "directional":
            return np.r_[-np.asarray(light.direction, np.float64), 0.0]
        return np.r_[np.asarray(light.position, np.float64), 1.0]

    def _grid_uniforms(self, frame: Frame) -> dict:
        frustum = fit_light(frame.scene, self.params.res)
        return dict(light_view_proj=frustum.view_proj, grid_res=self.params.res,
                    min_w=0.0 if frustum.is_ortho else frustum.near, light=self._light(frame))

    def _bind_storage(self) -> None:
        for binding, buffer in enumerate((self.positions, self.next, self.masks, self.bounds,
                                          self.offsets, None, self.missed)):
            if buffer is not None:
                buffer.bind(binding)

    def _samples(self, frame: Frame, grid: dict) -> None:
        self.bounds.write(EMPTY_BOUNDS if self.params.fit == "view" else PLAIN_BOUNDS)
        uniforms = dict(camera_position=frame.camera.position,
                        camera_inverse_view_proj=np.linalg.inv(frame.camera.view_proj), **grid)
        if self.jittered is None:
            self._place(frame, frame.bind_gbuffer, uniforms)
            return
        for k, offset in enumerate(self.pattern):
            if not offset.any():  # the pixel's centre: the frame's own camera pass
                self._place(frame, frame.bind_gbuffer, dict(uniforms, sample_index=k))
                continue
            # the camera pass again, moved by the sample's offset: its pixels see the
            # surfaces the sample's rays meet
            self.jittered.render(frame.geometry,
                                 jitter(offset, frame.width, frame.height) @ frame.camera.view_proj)
            self._place(frame, self._bind_jittered, dict(uniforms, sample_index=k))

    def _bind_jittered(self, program) -> None:
        program.set(gbuffer_position=self.jittered.position_texture.bind(0),
                    gbuffer_normal=self.jittered.normal_texture.bind(1))

    def _place(self, frame: Frame, bind_gbuffer, uniforms: dict) -> None:
        """One dispatch of the samples shader over the pixels."""
        self._bind_storage()
        program = self.samples_program.use()
        bind_gbuffer(program)
        program.set(**uniforms)
        if self.offsets is None:
            GL.glUniform2fv(program.location("offsets"), self.params.samples, self.pattern)
        GL.glDispatchCompute(-(-frame.width // GROUP), -(-frame.height // GROUP), 1)
        GL.glMemoryBarrier(GL.GL_SHADER_STORAGE_BARRIER_BIT)
        GL.glUseProgram(0)

    def _lists(self, program, grid: dict) -> None:
        self.heads.fill(END)
        self._bind_storage()
        self.heads.bind(0)
        program.use().set(slots=np.uint32(self.slots), **grid)
        GL.glDispatchCompute(-(-self.slots // LIST_GROUP), 1, 1)
        GL.glMemoryBarrier(GL.GL_SHADER_STORAGE_BARRIER_BIT | GL.GL_TEXTURE_FETCH_BARRIER_BIT)
        GL.glUseProgram(0)

    def _casters(self, frame: Frame, program, grid: dict) -> None:
        self._bind_storage()
        self.target.bind()
        for cap in (GL.GL_DEPTH_TEST, GL.GL_CULL_FACE, GL.GL_BLEND, GL.GL_STENCIL_TEST):
            GL.glDisable(cap)
        GL.glActiveTexture(GL.GL_TEXTURE0)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.heads.id)
        program.use().set(heads=0, **grid)
        frame.bind_alpha(program, 1)
        frame.draw_scene()
        GL.glMemoryBarrier(GL.GL_SHADER_STORAGE_BARRIER_BIT)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        GL.glViewport(0, 0, frame.width, frame.height)
        GL.glUseProgram(0)

    def _visibility(self, frame: Frame) -> None:
        frame.begin_visibility()
        self._bind_storage()
        self.visibility_program.use().set(width=frame.width)
        frame.draw_fullscreen(covered_only=True)

    def _count(self, frame: Frame, grid: dict) -> dict:
        """The lists' and casters' work, counted untimed by the same passes again (their
        masks come out the same) whenever the light, the camera or an object moved."""
        light = frame.scene.light
        key = tuple(b"" if v is None else np.asarray(v).tobytes()
                    for v in (light.direction, light.position, frame.camera.view_proj,
                              frame.part_poses))
        if key == self.counted[0]:
            return dict(self.counted[1])
        lengths, totals = IntegerImage(self.params.res), StorageBuffer(12)
        try:
            lengths.fill(0)
            lengths.bind(1)
            self._lists(self.list_programs[1], grid)
            totals.write(np.zeros(3, np.uint32))
            totals.bind(5)
            self._casters(frame, self.caster_programs[1], grid)
            fragments, tests, alpha_tests = (int(v) for v in totals.read(np.uint32, 3))
            per_texel = lengths.read()
        finally:
            for resource in (lengths, totals):
                resource.release()
        counted = {**list_statistics(per_texel), "samples_inserted": int(per_texel.sum()),
                   "caster_fragments": fragments, "sample_tests": tests,
                   **({"alpha_tests": alpha_tests} if frame.scene.has_alpha else {}),
                   # the cost model's counted work (harness.analysis.cost_model): a sample
                   # linked is one step of the structure, a sample tested one triangle test
                   "traversal_nodes": int(per_texel.sum()), "triangle_tests": tests}
        self.counted = (key, counted)
        return dict(counted)

    def render(self, frame: Frame) -> ShadowOutput:
        grid = self._grid_uniforms(frame)
        with frame.measure("samples"):
            self._samples(frame, grid)
        with frame.measure("lists"):
            self._lists(self.list_programs[0], grid)
        with frame.measure("casters"):
            self._casters(frame, self.caster_programs[0], grid)
        with frame.measure("visibility"):
            self._visibility(frame)
        extra = self._count(frame, grid)
        warnings = []
        if extra["lists_over_limit"]:
            warnings.append(f"izb: {extra['lists_over_limit']} lists longer than llvmpipe's "
                            f"{LOOP_LIMIT} loop iterations (the longest {extra['list_max']}): "
                            f"their tails were not tested, lit; a larger res shortens them")
        # the mask's read, and each alpha test's four texels (alpha_test.glsl) per pixel
        covered = int(np.count_nonzero(frame.arrays.covered))
        fetches = 1 + 4 * extra.get("alpha_tests", 0) / max(covered, 1)
        return frame.output(mem_bytes=self.mem_bytes, fetches_per_px=fetches, extra=extra,
                            warnings=warnings)

    @property
    def mem_bytes(self) -> int:
        return sum(b.nbytes for b in (self.positions, self.next, self.masks, self.offsets,
                                      self.missed, self.heads) if b is not None) + (
            0 if self.jittered is None else self.jittered.fbo.nbytes)

    def release(self) -> None:
        for resource in (self.samples_program, *self.list_programs, *self.caster_programs,
                         self.visibility_program, self.positions, self.next, self.masks,
                         self.bounds, self.offsets, self.missed, self.jittered, self.heads,
                         self.target):
            if resource is not None:
                resource.release()
