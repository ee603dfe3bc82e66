"""The light depth map shared by the map-based techniques (a helper, not a technique)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Literal

import numpy as np
from OpenGL import GL

from harness.config import MAX_COORDINATE
from harness.gl.framebuffer import Framebuffer, Texture
from harness.technique import Frame, Technique
from harness.scene.transforms import CUBE_AXES, LightFrustum, cube_faces, fit_light

# Upper bounds of the map techniques' length-like knobs, stated in each one's table: a constant
# bias in scene units at most MAX_COORDINATE (no scene is larger: harness.config.limits);
# slope_bias and normal_offset, which reach that many texels of the map, at most MAX_TEXELS (at
# 64 texels a 256-texel map's bias spans a quarter of the map: a typo, never a setting;
# normal_offset 1e9 took every shadow away without a word).
MAX_BIAS = MAX_COORDINATE
MAX_TEXELS = 64.0

# How each depth read's receiver depth is formed (shadow_map.glsl's header): ``slope`` the
# bound depth - |g| |c - u|, ``receiver_plane`` the plane's extrapolation depth + g . (c - u),
# ``adaptive`` the depth where the light ray through the read texel's centre meets the
# receiver's tangent plane (Dou et al. 2014), with neither the constant bias nor slope_bias.
# Every map technique's ``bias_mode``.
BiasMode = Literal["slope", "receiver_plane", "adaptive"]
BIAS_MODES = {"slope": 0, "receiver_plane": 1, "adaptive": 2}


def bias_uniforms(mode: str) -> dict:
    """The uniforms of shadow_map.glsl that pick ``mode``."""
    return dict(bias_mode=BIAS_MODES[mode])

# What `shadowbench tune` searches of the bias rule every map technique shares (shadow_map.glsl):
# the constant bias over six decades of scene units around the default 0.02 (scenes here span
# 1 to 1e5 units), the slope term from none to four times its default, the normal offset from
# none to two texels; all three are the bias terms the bias window scales together.
BIAS_TUNING = {"bias": ("log", 1e-5, 10.0), "slope_bias": ("float", 0.0, 4.0),
               "normal_offset": ("float", 0.0, 2.0)}
BIAS_TERMS = ("bias", "slope_bias", "normal_offset")
# the bias mode (above): which receiver depth each read is compared with
BIAS_MODE_TUNING = {"bias_mode": ("choice", tuple(BIAS_MODES))}

# Clear value of the map: "no occluder in this texel", so every receiver there is lit.
EMPTY_DEPTH = 3.0e38


def count_alpha_tests(draw: Callable[[], None]) -> int:
    """The alpha tests ``draw`` runs with a program built with COUNT_ALPHA_TESTS
    (cut_out_texel.glsl): an atomic counter at binding 0, zeroed before, read after."""
    counter = GL.glGenBuffers(1)
    try:
        GL.glBindBuffer(GL.GL_ATOMIC_COUNTER_BUFFER, counter)
        GL.glBufferData(GL.GL_ATOMIC_COUNTER_BUFFER, 4, np.zeros(1, np.uint32),
                        GL.GL_DYNAMIC_READ)
        GL.glBindBufferBase(GL.GL_ATOMIC_COUNTER_BUFFER, 0, counter)
        draw()
        GL.glMemoryBarrier(GL.GL_ATOMIC_COUNTER_BARRIER_BIT)
        GL.glBindBuffer(GL.GL_ATOMIC_COUNTER_BUFFER, counter)
        return int(np.frombuffer(GL.glGetBufferSubData(GL.GL_ATOMIC_COUNTER_BUFFER, 0, 4),
                                 np.uint32)[0])
    finally:
        GL.glBindBuffer(GL.GL_ATOMIC_COUNTER_BUFFER, 0)
        GL.glDeleteBuffers(1, [counter])


class _DepthMapResources:
    """What every light depth map holds: its framebuffer, the program drawing linear depth, and
    the light frusta it is drawn with (``frusta``). On a scene with alpha-tested casters the
    program cuts them out (``ALPHA_TEST``: a cut-out texel writes no depth) unless ``cutouts``
    is False (a technique that ignores them draws them opaque)."""

    def __init__(self, frame: Frame, fbo: Framebuffer, cutouts: bool):
        self.fbo = fbo
        self.alpha_test = cutouts and frame.scene.has_alpha
        defines = {"ALPHA_TEST": 1} if self.alpha_test else {}
        self.program = Technique.shader(__file__, "light_depth.vert.glsl",
                                        "light_depth.frag.glsl", **defines)
        self.counted = (None, 0)  # what the alpha tests were last counted for, and how many
        self.counting = None  # the counting program, made when first needed

    def render(self, frame: Frame) -> None:
        raise NotImplementedError

    def alpha_tests(self, frame: Frame) -> int:
        """Fragments of the map's depth pass that ran the alpha test (4 texels each), counted
        untimed by drawing the map again with a counting program (the same depths), whenever
        the light or the geometry moved: a diagnostic, as rt's counted rays. 0 without
        cut-outs."""
        if not self.alpha_test:
            return 0
        key = b"".join(np.asarray(m, np.float64).tobytes() for f in self.frusta
                       for m in (f.view, f.proj)) + frame.part_poses.tobytes()
        if key == self.counted[0]:
            return self.counted[1]
        if self.counting is None:
            self.counting = Technique.shader(__file__, "light_depth.vert.glsl",
                                             "light_depth.frag.glsl", ALPHA_TEST=1,
                                             COUNT_ALPHA_TESTS=1)
        drawing, scratch = self.program, frame.new_meter()

        def draw() -> None:
            scratch.new_frame(measuring=False)  # its passes are timed nowhere
            with frame.metered(scratch):
                self.render(frame)

        try:
            self.program = self.counting
            tests = count_alpha_tests(draw)
        finally:
            self.program = drawing
            scratch.release()
        self.counted = (key, tests)
        return tests

    def use_program(self, frame: Frame, frustum: LightFrustum) -> None:
        """Bind the depth program for ``frustum`` (and the cut-outs' textures it reads)."""
        self.program.use().set(light_view=frustum.view, light_proj=frustum.proj)
        if self.alpha_test:
            frame.bind_alpha(self.program, 0)

    @property
    def mem_bytes(self) -> int:
        return self.fbo.nbytes

    @property
    def nonfinite(self) -> int:
        return int(sum(np.count_nonzero(~np.isfinite(m)) for f in self.frusta
                       for m in (f.view, f.proj)))

    def release(self) -> None:
        self.fbo.release()
        self.program.release()
        if self.counting is not None:
            self.counting.release()


class LightDepthMap(_DepthMapResources):
    """A res x res linear-depth map (R32F) rendered from the scene's light."""

    def __init__(self, frame: Frame, res: int, frustum: LightFrustum | None = None,
                 cutouts: bool = True):
        self.res = res
        self.frustum = frustum or fit_light(frame.scene, res)
        super().__init__(frame, Framebuffer(res, res, (GL.GL_R32F,), depth=True), cutouts)

    @property
    def frusta(self) -> list[LightFrustum]:
        return [self.frustum]

    def fit(self, frame: Frame) -> None:
        self.frustum = fit_light(frame.scene, self.res)

    def render(self, frame: Frame) -> None:
        self.fbo.clear((EMPTY_DEPTH,) * 4)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        self.use_program(frame, self.frustum)
        frame.draw_scene()

    def lookup_uniforms(self, unit: int, slope_bias: float, frame: Frame,
                        texture: Texture | None = None) -> dict:
        """Uniforms of shadow_map.glsl, with the map bound to texture ``unit``; ``slope_bias``
        scales its slope term (receiver plane's slope x each read's distance).

        ``texture`` replaces the depth map by another res x res texture on the same frustum
        (e.g. one holding several depths per cell)."""
        f = self.frustum
        texture = texture or self.fbo.colors[0]
        return dict(shadow_map=texture.bind(unit), light_view=f.view, light_proj=f.proj,
                    map_res=float(self.res), light_is_ortho=f.is_ortho, slope_bias=slope_bias,
                    depth_precision=depth_precision(frame.scene.bounds, f.view))


# The guard band of a point light's faces, in texels per side: half the largest
# percentage-closer region (MAX_FOOTPRINT in pcf_samples.glsl), so a region centred on a point
# at its face's edge still reads that face's depths, never past its edge (which would count
# as lit: with 16 texels pcf still leaked on hard_point_ring's diagonal seams at map 1024).
CUBE_GUARD_TEXELS = 32
# pass names: shadow_map_px for the face along +x, ...
_FACE_NAMES = tuple(("p" if axis.sum() > 0 else "n") + "xyz"[int(np.abs(axis).argmax())]
                    for axis in CUBE_AXES)


class CubeDepthMap(_DepthMapResources):
    """A point light's depth map: six linear-depth faces (the layers of an R32F array, over one
    depth buffer), each rendered in a timed pass of its own. Each face's own 90 degrees span
    ``res`` texels; ``guard`` more texels on every side hold its neighbours' nearest
    directions, so a face is res + 2 guard texels wide."""

    def __init__(self, frame: Frame, res: int, guard: int = 0):
        self.res, self.size = res, res + 2 * guard
        self.half_tan = self.size / res
        self.fit(frame)
        super().__init__(frame, Framebuffer(self.size, self.size, (GL.GL_R32F,), depth=True,
                                            layers=len(CUBE_AXES)), cutouts=True)

    @property
    def frusta(self) -> list[LightFrustum]:
        return self.faces

    def fit(self, frame: Frame) -> None:
        self.faces = cube_faces(frame.scene, self.size, self.half_tan)

    def render(self, frame: Frame) -> None:
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        for layer, (face, name) in enumerate(zip(self.faces, _FACE_NAMES)):
            with frame.measure(f"shadow_map_{name}"):
                self.fbo.colors[0].clear(EMPTY_DEPTH, layer)
                self.fbo.attach_layer(layer)
                self.fbo.depth.clear_depth_stencil(0)
                self.use_program(frame, face)
                frame.draw_scene()

    def lookup_uniforms(self, unit: int, slope_bias: float, frame: Frame) -> dict:
        """Uniforms of shadow_map.glsl built with CUBE_FACES (cube_faces.glsl)."""
        first = self.faces[0]
        return dict(shadow_map=self.fbo.colors[0].bind(unit),
                    face_views=np.stack([f.view for f in self.faces]), light_proj=first.proj,
                    light_position=frame.scene.light.position, map_res=float(self.size),
                    light_is_ortho=False, slope_bias=slope_bias,
                    depth_precision=depth_precision(frame.scene.bounds, first.view))


def alpha_fetches_per_px(frame: Frame, *maps: _DepthMapResources) -> float:
    """The alpha texels the maps' depth passes read (4 per alpha test, see
    :meth:`_DepthMapResources.alpha_tests`), per shaded (covered) pixel: what the cut-outs add
    to a map technique's ``fetches_per_px``."""
    covered = int(frame.arrays.covered.sum())
    return 4 * sum(m.alpha_tests(frame) for m in maps) / max(covered, 1)


# Depths and G-buffer positions are float32: far from the origin their rounding alone makes a
# lit receiver fail its own depth test. 4 units in the last place of the largest coordinate
# cleared it on hard_far_from_origin (1e5 from the origin: sm 0.29 % wrong, all of it acne,
# with no such term; 0.009 % with 2^-21 x 1e5 = 0.048 units); near the origin it is
# negligible (1e-5 units on a scene 20 units across).
PRECISION_ULPS = 4


def depth_precision(bounds: np.ndarray, light_view: np.ndarray) -> float:
    """Depth rounding of float32 coordinates as large as the scene's or the light view's
    translation, in scene units: a bias every depth test adds to its own."""
    magnitude = max(float(np.abs(bounds).max()), float(np.abs(light_view[:3, 3]).max()))
    return PRECISION_ULPS * magnitude * 2.0 ** -23


@dataclass(frozen=True)
class Sampling:
    """Where the percentage-closer samples of one pixel fall and how each is biased (the
    uniforms of pcf_samples.glsl; its header says what each means)."""

    grid_n: int = 1
    footprint_region: bool = False  # the pixel's footprint in the map, else a fixed region
    res_factor: float = 1.0  # footprint region: times the footprint
    min_size: float = 1.0  # footprint region: smallest side, texels
    spacing: float = 1.0  # fixed region: sub-region side, texels
    jitter: bool = False
    seed: int = 0
    bias_min: float = 0.0  # constant bias drawn per sample, scene units
    bias_max: float = 0.0
    slope_bias: float = 1.0  # times the receiver plane's slope x each read's distance
    bias_mode: str = "slope"  # BiasMode: how each read's receiver depth is formed
    normal_offset: float = 0.0  # texels' world size x sin(light angle) along the normal
    window: tuple[int, int] = (0, 0)  # a texel's depths come from offsets window[0]..window[1]


def camera_rays(frame: Frame) -> dict:
    """Uniforms giving the world-space camera ray through any window position (x, y):
    camera_ray + x camera_ray_dx + y camera_ray_dy (linear for a pinhole camera)."""
    inverse = np.linalg.inv(frame.camera.view_proj)
    origin = frame.camera.position

    def ray(x: float, y: float) -> np.ndarray:
        ndc = np.array([2 * x / frame.width - 1, 2 * y / frame.height - 1, 0.0, 1.0])
        point = inverse @ ndc
        direction = point[:3] / point[3] - origin
        return direction / -(frame.camera.view[2, :3] @ direction)  # unit view depth

    base = ray(0.0, 0.0)
    return dict(camera_position=origin, camera_ray=base, camera_ray_dx=ray(1.0, 0.0) - base,
                camera_ray_dy=ray(0.0, 1.0) - base)


class MapShading:
    """Two passes: the light depth map (``update``), then one full-screen pass writing V from it
    (``render``) with
    ``fragment``, the path of the technique's own shader built on ``shadow_map.glsl`` (``defines``
    go to it) that gives V = 1 where the G-buffer has no surface (those pixels are not shaded).
    A point light's map is a :class:`CubeDepthMap` (its faces widened by ``cube_guard``
    texels)."""

    def __init__(self, frame: Frame, res: int, fragment: Path, cube_guard: int = 0,
                 **defines):
        self.cube = frame.scene.light.type == "point"
        if self.cube:
            self.map = CubeDepthMap(frame, res, cube_guard)
            defines["CUBE_FACES"] = 1
        else:
            self.map = LightDepthMap(frame, res)
        self.shading = Technique.shader(__file__, "fullscreen.vert.glsl", fragment, **defines)

    def update(self, frame: Frame) -> None:
        """The map for the frame's light and geometry, each step timed: its fit, then its pass
        (the work ``cost: static`` charges once)."""
        with frame.measure("light_fit"):
            self.map.fit(frame)
        if self.cube:
            self.map.render(frame)  # a timed pass per face
        else:
            with frame.measure("shadow_map"):
                self.map.render(frame)

    def render(self, frame: Frame, slope_bias: float, **uniforms) -> None:
        """The shading pass on the map of the last ``update``; ``uniforms`` go to the shading
        shader."""
        self.shade(frame, slope_bias, **uniforms)

    def shade(self, frame: Frame, slope_bias: float, texture: Texture | None = None,
              **uniforms) -> None:
        """The shading pass alone, on the map already rendered (or on ``texture``)."""
        with frame.measure("shading"):
            frame.begin_visibility()
            self.shading.use()
            unit = frame.bind_gbuffer(self.shading)
            lookup = (self.map.lookup_uniforms(unit, slope_bias, frame) if self.cube
                      else self.map.lookup_uniforms(unit, slope_bias, frame, texture))
            self.shading.set(**lookup, **uniforms)
            frame.draw_fullscreen(covered_only=True)  # V = 1 where no surface

    def release(self) -> None:
        self.map.release()
        self.shading.release()


class FilteredShadowMap:
    """The map and a full-screen PCF shading pass (:class:`MapShading`) with the samples of a
    :class:`Sampling`.

    ``fragment`` is the path of the technique's shading shader built on ``pcf_samples.glsl``
    (the same samples, its own per-sample test; ``defines`` go to it)."""

    def __init__(self, frame: Frame, res: int, fragment: Path, **defines):
        self.passes = MapShading(frame, res, fragment, cube_guard=CUBE_GUARD_TEXELS, **defines)

    @property
    def map(self) -> LightDepthMap | CubeDepthMap:
        return self.passes.map

    def update(self, frame: Frame) -> None:
        self.passes.update(frame)

    def render(self, frame: Frame, sampling: Sampling) -> None:
        self.passes.render(frame, sampling.slope_bias, **sampling_uniforms(frame, sampling))

    def shade(self, frame: Frame, sampling: Sampling, texture: Texture | None = None) -> None:
        """The shading pass alone, on the map already rendered (or on ``texture``)."""
        self.passes.shade(frame, sampling.slope_bias, texture,
                          **sampling_uniforms(frame, sampling))

    def release(self) -> None:
        self.passes.release()


def sampling_uniforms(frame: Frame, sampling: Sampling) -> dict:
    """The uniforms of pcf_samples.glsl for ``sampling`` in ``frame``."""
    s = sampling
    return dict(**camera_rays(frame), grid_n=s.grid_n, footprint_region=s.footprint_region,
                res_factor=s.res_factor, min_size=s.min_size, spacing=s.spacing,
                bias_min=s.bias_min, bias_max=s.bias_max, normal_offset=s.normal_offset,
                **bias_uniforms(s.bias_mode), jitter=s.jitter,
                window_low=np.full(2, float(s.window[0])),
                window_high=np.full(2, float(s.window[1])), seed=np.uint32(s.seed))
