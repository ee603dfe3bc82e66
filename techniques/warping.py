"""Perspective reparameterization of a directional light's shadow map (a helper, not a technique).

Shared by ``psm``, ``lispsm`` and ``gmnpr``: the body B of points that need shadow-map
resolution (the view frustum clipped to the scene bounds, extended toward the light to its
casters), the light-space warp of Wimmer et al. 2004 (warp axis = view direction projected
perpendicular to the light), the post-perspective light of Stamminger and Drettakis 2002, the
fit of the warped body to the unit cube, the lambda formulas of Zhang et al. (equations 4, 8, 9
of "Generalized Minimum-Norm Perspective Shadow Maps") and its analytic aliasing F (equation 2).

Every map is expressed as a :class:`harness.transforms.LightFrustum`: ``view`` is a rigid light
basis whose -z is the light's travel direction, centred on the camera (a local origin, so the
float32 GL passes keep their precision far from the world origin), so map depth stays the linear
distance along the light; ``proj`` carries the whole warp. A texel is one world light ray in
all three warps, so that linear depth orders occluders correctly within a texel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from OpenGL import GL
from pydantic import Field

from harness import metrics
from harness.config import SquareInt
from harness.technique import Frame, NotApplicable, ShadowOutput, Technique, TechniqueParams
from harness.transforms import LightFrustum, look_at

from .shadowmap import LightDepthMap

# lambda is clamped here: at theta = 0 both LiSPSM's and GMNPR's lambda are infinite (the
# standard shadow map); 1e4 body depths of warp distance is indistinguishable from it.
LAMBDA_MAX = 1.0e4
# Fraction of the fitted extent left as margin on each side of the unit cube.
CUBE_MARGIN = 1.0e-3


# --- lambda and F (the paper's 2-D model: n, f view depths, phi half field of view) -----------


def lambda_minimum_norm(theta, phi, n, f):
    """Equation 4: the lambda making F(n) = F(f) (lambda_1 above phi, lambda_2 below)."""
    theta = np.asarray(theta, dtype=np.float64)
    t = math.tan(phi) / np.tan(np.maximum(theta, 1e-300))
    lam1 = (n + math.sqrt(f * n) - n * t) / (f - n + (f + n) * t)
    lam2 = (f + math.sqrt(f * n)) / (2 * f) / t - 0.5
    return np.where(theta >= phi, lam1, lam2)


def lambda_gmnpr(theta, phi, n, f):
    """Equation 8: lambda_1 for theta in [phi, pi/2], lambda_1(phi) / tan(pi theta / (4 phi))
    below, so lambda is continuous at phi and grows to infinity (the plain map) at theta = 0."""
    theta = np.asarray(theta, dtype=np.float64)
    below = math.sqrt(f * n) / (2 * f) / np.tan(np.pi * np.maximum(theta, 1e-300) / (4 * phi))
    return np.where(theta >= phi, lambda_minimum_norm(np.maximum(theta, phi), phi, n, f), below)


def lambda_lispsm(theta, phi, n, f):
    """Equation 9: Wimmer's n_opt = (n + sqrt(f n)) / sin(theta) over the body depth P_f - P_n."""
    theta = np.maximum(np.asarray(theta, dtype=np.float64), 1e-300)
    t = math.tan(phi) / np.tan(theta)
    depth = np.where(theta >= phi, (f - n + (f + n) * t) * np.sin(theta),
                     2 * f * math.tan(phi) * np.cos(theta))
    return (n + math.sqrt(f * n)) / np.sin(theta) / depth


def aliasing_F(lam, theta, z, phi, n, f):
    """Equation 2: perspective aliasing F(lambda, theta, z) = psi (z + varphi)^2 / z."""
    lam, theta, z = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (lam, theta, z)))
    t = math.tan(phi) / np.tan(np.maximum(theta, 1e-300))
    a = f - n + (f + n) * t
    psi = np.where(theta >= phi, 1 / (math.tan(phi) * a * lam * (lam + 1)),
                   1 / (math.tan(phi) * 2 * f * lam * (lam + 1) / t))
    varphi = np.where(theta >= phi, a * lam + n * t - n, f * (2 * lam + 1) * t - f)
    return psi * (z + varphi) ** 2 / z


# --- the body B -------------------------------------------------------------------------------


def _planes_of(matrix: np.ndarray) -> np.ndarray:
    """The six inward half-spaces (a . p + d >= 0, |a| = 1) of a clip matrix's frustum."""
    rows = [matrix[3] + s * matrix[i] for i in range(3) for s in (1, -1)]
    planes = np.array(rows)
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


def _box_planes(bounds: np.ndarray) -> np.ndarray:
    planes = []
    for axis in range(3):
        normal = np.zeros(3)
        normal[axis] = 1
        planes.append([*normal, -bounds[0, axis]])
        planes.append([*-normal, bounds[1, axis]])
    return np.array(planes)


def convex_vertices(planes: np.ndarray, tolerance: float) -> np.ndarray:
    """Vertices of the convex polytope {p : a . p + d >= 0}: every three-plane intersection
    inside all the half-spaces (coincident planes of a flat box are simply singular triples)."""
    triples = np.array(list(combinations(range(len(planes)), 3)))
    a, d = planes[triples, :3], planes[triples, 3]
    det = np.linalg.det(a)
    ok = np.abs(det) > 1e-9
    points = np.linalg.solve(a[ok], -d[ok][..., None])[..., 0]
    inside = np.all(points @ planes[:, :3].T + planes[:, 3] >= -tolerance, axis=1)
    return points[inside]


def padded_bounds(bounds: np.ndarray) -> np.ndarray:
    """Scene bounds grown a little, so surfaces on the box itself stay strictly inside."""
    pad = 1e-4 * max(float(np.linalg.norm(bounds[1] - bounds[0])), 1e-6)
    return np.stack([bounds[0] - pad, bounds[1] + pad])


def receiver_body(view_proj: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Vertices of the view frustum clipped to the scene bounds: every visible receiver lies in
    their hull. An empty intersection (nothing in view) falls back to the box corners."""
    box = padded_bounds(bounds)
    scale = max(float(np.abs(box).max()), 1.0)
    points = convex_vertices(np.vstack([_planes_of(view_proj), _box_planes(box)]), 1e-7 * scale)
    if len(points) < 1:
        points = np.array([[box[i, 0], box[j, 1], box[k, 2]]
                           for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    return points


def _exit_times(points: np.ndarray, to_light: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Per point and axis, the travel along ``to_light`` to that axis' box face (inf if none)."""
    face = np.where(to_light > 0, box[1], box[0])
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t = (face - points) / to_light
    return np.where(np.abs(to_light) > 1e-12, np.maximum(t, 0), np.inf)


def caster_body(receivers: np.ndarray, to_light: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Receivers plus the vertices of their sweep toward the light, clipped to the scene bounds.

    The sweep's vertices are the exit points of the receiver vertices and of the points on the
    segments between them where the exit face changes (where two per-axis exit times are equal):
    there a swept edge meets a box edge.
    """
    box = padded_bounds(bounds)
    seeds = [receivers]
    if len(receivers) > 1:
        pairs = np.array(list(combinations(range(len(receivers)), 2)))
        a, b = receivers[pairs[:, 0]], receivers[pairs[:, 1]]
        ta, tb = _exit_times(a, to_light, box), _exit_times(b, to_light, box)
        for i, j in combinations(range(3), 2):
            with np.errstate(divide="ignore", invalid="ignore"):
                u = (ta[:, j] - ta[:, i]) / ((tb[:, i] - ta[:, i]) - (tb[:, j] - ta[:, j]))
            keep = np.isfinite(u) & (u > 0) & (u < 1)
            seeds.append(a[keep] + u[keep, None] * (b[keep] - a[keep]))
    seeds = np.vstack(seeds)
    t = _exit_times(seeds, to_light, box).min(axis=1)
    t = np.where(np.isfinite(t), t, 0.0)
    return np.vstack([receivers, seeds + t[:, None] * to_light])


# --- the camera and the light angle ---------------------------------------------------------


@dataclass(frozen=True)
class ViewSetup:
    """What the warps need of the camera and the light, in world space."""

    view: np.ndarray  # world -> camera view
    proj: np.ndarray
    eye: np.ndarray
    forward: np.ndarray  # unit view direction
    light: np.ndarray  # unit direction the light travels
    near: float
    far: float
    bounds: np.ndarray

    @property
    def view_proj(self) -> np.ndarray:
        return self.proj @ self.view

    @property
    def theta(self) -> float:
        """Angle between light and view directions folded to [0, pi/2] (the paper's symmetry)."""
        return math.acos(min(abs(float(self.forward @ self.light)), 1.0))

    @property
    def phi(self) -> float:
        """Half the frustum's angle in the plane of the view and light directions: the support
        of the image rectangle toward the light, so the body's extent along the warp axis is the
        paper's 2-D one (vertical half field of view for a light in the vertical plane)."""
        across = self.light - (self.light @ self.forward) * self.forward
        norm = np.linalg.norm(across)
        tan_x, tan_y = 1 / self.proj[0, 0], 1 / self.proj[1, 1]
        if norm < 1e-12:
            return math.atan(tan_y)
        cx, cy = (self.view[:2, :3] @ across) / norm
        return math.atan(tan_x * abs(cx) + tan_y * abs(cy))


def view_setup(frame) -> ViewSetup:
    """The camera and light of a frame; raises NotApplicable for anything but a directional."""
    light = frame.scene.light
    if light.type != "directional":
        raise NotApplicable(f"perspective warps here need a directional light, not {light.type}")
    cam = frame.scene.config.camera
    view = frame.camera.view
    return ViewSetup(view, frame.camera.proj, frame.camera.position, -view[2, :3],
                     np.asarray(light.direction, dtype=np.float64) / np.linalg.norm(light.direction),
                     float(cam.near), float(cam.far), frame.scene.bounds)


def light_basis(light: np.ndarray, forward: np.ndarray) -> np.ndarray:
    """Rigid world -> light view (no translation): -z = light travel, y = warp axis (the view
    direction projected perpendicular to the light; the camera's side when they are parallel)."""
    warp = forward - (forward @ light) * light
    if np.linalg.norm(warp) < 1e-9:
        helper = np.eye(3)[np.argmin(np.abs(light))]
        warp = helper - (helper @ light) * light
    warp /= np.linalg.norm(warp)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = np.cross(warp, -light), warp, -light
    return m


# --- the unit-cube fit ----------------------------------------------------------------------


def _homogeneous(points: np.ndarray) -> np.ndarray:
    return np.hstack([points, np.ones((len(points), 1))])


def cube_fit(clip: np.ndarray, receivers: np.ndarray, body: np.ndarray) -> np.ndarray:
    """Scale and offset ``clip`` so the receivers fill [-1, 1] in map x and y and the whole body
    (casters included) [-1, 1] in depth."""
    def ndc(points):
        c = _homogeneous(points) @ clip.T
        return c[:, :3] / c[:, 3:]

    r, b = ndc(receivers), ndc(body)
    lo = np.array([*r[:, :2].min(0), b[:, 2].min()])
    hi = np.array([*r[:, :2].max(0), b[:, 2].max()])
    half = np.maximum((hi - lo) / 2, 1e-12) * (1 + CUBE_MARGIN)
    fit = np.eye(4)
    fit[:3, :3] = np.diag(1 / half)
    fit[:3, 3] = -(hi + lo) / 2 / half
    return fit @ clip


def local_light_view(basis: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """The rigid light basis moved so that ``origin`` maps to the light-view origin."""
    view = basis.copy()
    view[:3, 3] = -basis[:3, :3] @ origin
    return view


def frustum_from_clip(light_view: np.ndarray, clip: np.ndarray, res: int,
                      origin: np.ndarray) -> LightFrustum:
    """A LightFrustum whose view is the rigid light basis translated to ``origin`` (a local
    origin near the camera) and whose proj carries the warp.

    The GL passes run in float32: with an untranslated basis, a scene far from the world origin
    (1e5 units) puts light-view coordinates of size 1e5 into proj, whose perspective rows then
    subtract translations of that size and amplify the float32 rounding into texels. Relative
    to a nearby origin, proj sees small coordinates and only the rigid view meets the large ones.
    ``texel_world`` is unused by the warped shading (it computes the texel size per pixel)."""
    view = local_light_view(light_view, np.asarray(origin, dtype=np.float64))
    return LightFrustum(view, clip @ np.linalg.inv(view), False, 1.0 / res, 0.0, 0.0)


# --- light-space perspective (LiSPSM, GMNPR) -----------------------------------------------


@dataclass(frozen=True)
class Warp:
    frustum: LightFrustum
    clip: np.ndarray  # world -> clip of the map
    theta: float
    phi: float
    lam: float
    near: float  # view depth range of the receiver body: the n and f of the formulas
    far: float


def body_depth_range(setup: ViewSetup, receivers: np.ndarray) -> tuple[float, float]:
    depth = -(_homogeneous(receivers) @ setup.view[2])
    near = max(float(depth.min()), setup.near)
    return near, max(float(depth.max()), near * (1 + 1e-6))


def light_space_warp(setup: ViewSetup, res: int, choose_lambda) -> Warp:
    """Wimmer's warp: a perspective frustum P along the warp axis with its eye lambda body depths
    before the body, laterally at the camera; orthographic along the light after it.
    ``choose_lambda(theta, phi, n, f)`` is the technique's lambda."""
    receivers = receiver_body(setup.view_proj, setup.bounds)
    body = caster_body(receivers, -setup.light, setup.bounds)
    basis = light_basis(setup.light, setup.forward)
    local = _homogeneous(body) @ basis.T
    along = local[:, 1]
    depth = max(float(along.max() - along.min()), 1e-9)
    near, far = body_depth_range(setup, receivers)
    theta, phi = setup.theta, setup.phi
    lam = float(np.clip(choose_lambda(theta, phi, near, far), 1e-6, LAMBDA_MAX))
    p_near = lam * depth
    eye = basis[:3, :3] @ setup.eye
    # P's eye: the camera's lateral position, p_near before the body along the warp axis
    origin = np.array([eye[0], along.min() - p_near, 0.0])
    to_p = np.eye(4)
    to_p[:3, 3] = -origin
    p_far = p_near + depth
    # rows: map x (lateral), map y (hyperbolic warp-axis depth), map depth (along the light,
    # away from it), w (distance along the warp axis)
    warp = np.array([[1, 0, 0, 0],
                     [0, (p_far + p_near) / (p_far - p_near), 0, -2 * p_far * p_near / (p_far - p_near)],
                     [0, 0, -1, 0],
                     [0, 1, 0, 0]], dtype=np.float64)
    clip = cube_fit(warp @ to_p @ basis, receivers, body)
    return Warp(frustum_from_clip(basis, clip, res, setup.eye), clip, theta, phi, lam, near, far)


# --- post-perspective space (PSM) -----------------------------------------------------------


@dataclass(frozen=True)
class PostPerspective:
    frustum: LightFrustum
    clip: np.ndarray
    theta: float
    slide_back: float  # how far the virtual camera moved back to see every caster
    light_kind: str  # "point", "inverted" (light behind the viewer) or "directional"


def post_perspective_warp(setup: ViewSetup, res: int) -> PostPerspective:
    """Stamminger and Drettakis: the map is made in the post-perspective space of a virtual
    camera slid back until every caster is in front of its near plane (at the real near
    distance); the directional light becomes a point there, an inverted point (depth order
    reversed, Kozlov's inverse projection) when it is behind the viewer, or stays directional
    when it is perpendicular to the view. The light frustum is fitted to the receivers' part of
    the unit cube (unit-cube clipping)."""
    receivers = receiver_body(setup.view_proj, setup.bounds)
    body = caster_body(receivers, -setup.light, setup.bounds)
    depth = -(_homogeneous(body) @ setup.view[2])
    slide = max(0.0, setup.near - float(depth.min()))
    near = float(depth.min()) + slide
    far = max(float(depth.max()) + slide, near * (1 + 1e-6))
    virtual_view = setup.view.copy()
    virtual_view[2, 3] -= slide  # view z of every point moves by -slide
    virtual_proj = setup.proj.copy()
    virtual_proj[2, 2] = -(far + near) / (far - near)
    virtual_proj[2, 3] = -2 * far * near / (far - near)
    camera = virtual_proj @ virtual_view

    def post(points):
        c = _homogeneous(points) @ camera.T
        return c[:, :3] / c[:, 3:]

    r_post, b_post = post(receivers), post(body)
    light4 = camera @ np.append(-setup.light, 0.0)
    centre = (r_post.min(0) + r_post.max(0)) / 2
    extent = float(np.linalg.norm(b_post.max(0) - b_post.min(0))) + 1e-12
    if abs(light4[3]) * extent < 1e-6 * np.linalg.norm(light4[:3]):
        kind = "directional"
        travel = -light4[:3] / np.linalg.norm(light4[:3])
        up = np.eye(3)[np.argmin(np.abs(travel))]
        light_view = look_at(centre - travel, centre, up)
        projection = np.diag([1.0, 1.0, -1.0, 1.0])  # depth grows away from the light
    else:
        kind = "point" if light4[3] > 0 else "inverted"
        position = light4[:3] / light4[3]
        aim = centre - position
        aim /= np.linalg.norm(aim)
        light_view = look_at(position, position + aim, np.eye(3)[np.argmin(np.abs(aim))])
        # divide by the distance d along the aim; depth -1/d grows away from a point light,
        # +1/d toward an inverted one (its occluders lie farther from the converging point)
        sign = 1.0 if kind == "point" else -1.0
        projection = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, -sign],
                               [0, 0, -1, 0]], dtype=np.float64)
    clip = cube_fit(projection @ light_view @ camera, receivers, body)
    basis = light_basis(setup.light, setup.forward)
    return PostPerspective(frustum_from_clip(basis, clip, res, setup.eye), clip, setup.theta, slide, kind)


# --- measurements ---------------------------------------------------------------------------


def map_coordinates(clip: np.ndarray, points: np.ndarray, res: int) -> tuple[np.ndarray, np.ndarray]:
    """Map texel coordinates (..., 2) and clip w (...) of world points (..., 3)."""
    c = np.einsum("ij,...j->...i", clip, np.concatenate([points, np.ones(points.shape[:-1] + (1,))], -1))
    with np.errstate(divide="ignore", invalid="ignore"):
        texel = (c[..., :2] / c[..., 3:] * 0.5 + 0.5) * res
    return texel, c


def outside_unit_cube(clip: np.ndarray, position: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Covered pixels whose world position falls outside the map's unit cube (or behind it)."""
    _, c = map_coordinates(clip, position, 1)
    w = c[..., 3]
    tolerance = 1e-5 * np.abs(w)
    inside = (w > 0) & np.all(np.abs(c[..., :3]) <= w[..., None] + tolerance[..., None], axis=-1)
    return covered & ~inside


def alias_map(clip: np.ndarray, res: int, position: np.ndarray, normal: np.ndarray,
              covered: np.ndarray) -> np.ndarray:
    """Per pixel, the largest screen extent of one map texel, in pixels (1 = a texel per pixel).

    From numpy finite differences of the map coordinates of the G-buffer world positions: J is
    d(texel)/d(pixel) from the right and lower neighbours, and a texel spans 1 / sigma_min(J)
    pixels. Pixels whose neighbours are not on their own plane (silhouettes, creases) get NaN.
    """
    texel, _ = map_coordinates(clip, position.astype(np.float64), res)
    h, w = covered.shape
    alias = np.full((h, w), np.nan)
    p, n = position.astype(np.float64), normal.astype(np.float64)
    centre, right, down = p[:-1, :-1], p[:-1, 1:], p[1:, :-1]
    scale = np.linalg.norm(right - centre, axis=-1) + np.linalg.norm(down - centre, axis=-1) + 1e-12
    on_plane = ((np.abs(np.einsum("...i,...i", right - centre, n[:-1, :-1])) < 1e-3 * scale)
                & (np.abs(np.einsum("...i,...i", down - centre, n[:-1, :-1])) < 1e-3 * scale))
    valid = covered[:-1, :-1] & covered[:-1, 1:] & covered[1:, :-1] & on_plane
    dx = texel[:-1, 1:] - texel[:-1, :-1]
    dy = texel[1:, :-1] - texel[:-1, :-1]
    jac = np.stack([dx, dy], axis=-1)  # (..., texel axis, pixel axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        sigma_min = np.linalg.svd(np.where(np.isfinite(jac), jac, 0.0), compute_uv=False)[..., -1]
        alias[:-1, :-1] = np.where(valid & np.all(np.isfinite(jac), axis=(-1, -2)),
                                   1.0 / sigma_min, np.nan)
    return alias


# --- the technique shared by psm, lispsm and gmnpr ------------------------------------------

PARAMETER_TABLE = """
    ==============  ================================================  =======  ===========
    Parameter       Meaning                                           Default  Range
    ==============  ================================================  =======  ===========
    ``res``         map width and height, texels                      1024     16 .. 8192
    ``bias``        constant depth bias, scene units                  0.02     >= 0
    ``slope_bias``  times the receiver plane's depth slope x each     1.0      >= 0
                    read's distance, in the warped map's texels
                    (shadow_map.glsl)
    ``k``           PCF samples per pixel, a square grid of texels    1        1 .. 49
    ==============  ================================================  =======  ===========
    """


class WarpParams(TechniqueParams):
    res: int = Field(1024, ge=16, le=8192)
    bias: float = Field(0.02, ge=0)
    slope_bias: float = Field(1.0, ge=0)
    k: SquareInt = Field(1, le=49)


class WarpedShadowMap(Technique):
    """A directional light's depth map under a warp chosen by ``warp(setup, res)`` (which
    returns a :class:`Warp` or :class:`PostPerspective` and the technique's extra columns),
    looked up by ``warp_shading.frag.glsl``. Spot lights are not applicable."""

    Params = WarpParams

    def warp(self, setup: ViewSetup, res: int) -> tuple[Warp | PostPerspective, dict]:
        raise NotImplementedError

    def prepare(self, frame: Frame) -> None:
        setup = view_setup(frame)
        res = self.params.res
        self.transform, columns = self.warp(setup, res)
        arrays = frame.arrays
        alias = alias_map(self.transform.clip, res, arrays.position, arrays.normal,
                          arrays.covered)
        outside = outside_unit_cube(self.transform.clip, arrays.position, arrays.covered)
        with np.errstate(divide="ignore", invalid="ignore"):
            self.alias_log2 = np.log2(alias)
        self.columns = dict(
            theta_deg=math.degrees(self.transform.theta),
            alias_mean=float(np.nanmean(alias)) if np.isfinite(alias).any() else float("nan"),
            alias_max=float(np.nanmax(alias)) if np.isfinite(alias).any() else float("nan"),
            outside_pct=100.0 * float(np.count_nonzero(outside))
            / max(np.count_nonzero(arrays.covered), 1),
            **columns)
        self.map = LightDepthMap(frame, res, frustum=self.transform.frustum)
        self.shading = Technique.shader(__file__, "fullscreen.vert.glsl", "warp_shading.frag.glsl")

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        with frame.measure("shadow_map"):
            # casters beyond the fitted depth range still occlude: clamp them, never clip them
            GL.glEnable(GL.GL_DEPTH_CLAMP)
            self.map.render(frame)
            GL.glDisable(GL.GL_DEPTH_CLAMP)
        with frame.measure("shading"):
            frame.begin_visibility()
            self.shading.use()
            unit = frame.bind_gbuffer(self.shading)
            uniforms = self.map.lookup_uniforms(unit, p.slope_bias, frame)
            uniforms.update(light_is_ortho=True, texel_world=1.0)
            self.shading.set(**uniforms)
            self.shading.set(grid_n=math.isqrt(p.k), bias=p.bias)
            frame.draw_fullscreen()
        warnings = []
        if self.columns["outside_pct"] > 0:
            warnings.append(f"{self.columns['outside_pct']:.2f}% of visible receivers fall "
                            "outside the warped map")
        return frame.output(mem_bytes=self.map.mem_bytes, fetches_per_px=p.k,
                            nonfinite=self.map.nonfinite + metrics.nonfinite(self.transform.clip),
                            extra=dict(self.columns), warnings=warnings,
                            maps={"pixels_per_texel_log2": self.alias_log2})

    def release(self) -> None:
        # prepare may have stopped early (NotApplicable for a spot light, a failed compile)
        for name in ("map", "shading"):
            resource = self.__dict__.pop(name, None)
            if resource is not None:
                resource.release()
