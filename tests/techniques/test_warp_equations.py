"""The warping module without GL: lambda (equations 4, 8, 9), F (equation 2, Figures 5 and 6)
and, over random cameras and lights, the properties every warped light transform must have."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from harness.truth import metrics
from harness.scene.transforms import look_at
from techniques.warps import warped_map as W

N, F, PHI = 1.0, 100.0, math.pi / 6
THETAS = [10.0, 30.0, 55.0, 90.0]


def warp_axis_extent(theta, phi, n, f):
    """P_f - P_n: the 2-D view frustum (depths n..f, half angle phi) projected onto the warp
    axis, which is perpendicular to a light at angle theta to the view (Figure 4)."""
    corners = [(z, s * z * math.tan(phi)) for z in (n, f) for s in (-1, 1)]
    axis = (math.sin(theta), math.cos(theta))  # (view depth, across) components
    along = [z * axis[0] + y * axis[1] for z, y in corners]
    return max(along) - min(along)


def minimum_norm_by_root(theta, phi, n, f):
    """Equation 3 solved numerically on equation 2: the lambda with F(n) = F(f)."""
    def gap(lam):
        return math.log(W.aliasing_F(lam, theta, n, phi, n, f) / W.aliasing_F(lam, theta, f, phi, n, f))
    return brentq(gap, 1e-9, 1e6, xtol=1e-14, rtol=1e-13)


@pytest.mark.parametrize("theta_deg", THETAS)
def test_lambda_equation_4_is_the_minimum_norm_root(theta_deg):
    theta = math.radians(theta_deg)
    t = math.tan(theta) / math.tan(PHI)
    if theta >= PHI:
        mu, nu = N / ((F - N) * t + F + N), 1 - F / ((F - N) * t + F + N)
    else:
        mu, nu = 0.5 - (F - N) / (2 * F) * t, 0.5
    from_mu_nu = (nu - mu) / (math.sqrt(F / N) - 1) - mu
    assert float(W.lambda_minimum_norm(theta, PHI, N, F)) == pytest.approx(from_mu_nu, rel=1e-12)
    if from_mu_nu > 0:
        assert from_mu_nu == pytest.approx(minimum_norm_by_root(theta, PHI, N, F), rel=1e-9)


@pytest.mark.parametrize("theta_deg", THETAS)
def test_lambda_equation_8_gmnpr(theta_deg):
    theta = math.radians(theta_deg)
    if theta >= PHI:
        c = math.tan(PHI) / math.tan(theta)
        expected = (N + math.sqrt(F * N) - N * c) / (F - N + (F + N) * c)
    else:
        expected = math.sqrt(F * N) / (2 * F) / math.tan(math.pi * theta / (4 * PHI))
    assert float(W.lambda_gmnpr(theta, PHI, N, F)) == pytest.approx(expected, rel=1e-12)
    assert expected > 0
    if theta >= PHI:  # and, independently of the printed formula: it is the minimum norm
        assert expected == pytest.approx(minimum_norm_by_root(theta, PHI, N, F), rel=1e-9)


@pytest.mark.parametrize("theta_deg", THETAS)
def test_lambda_equation_9_lispsm(theta_deg):
    theta = math.radians(theta_deg)
    n_opt = (N + math.sqrt(N * F)) / math.sin(theta)
    expected = n_opt / warp_axis_extent(theta, PHI, N, F)
    assert float(W.lambda_lispsm(theta, PHI, N, F)) == pytest.approx(expected, rel=1e-12)


def test_pinned_values_at_ninety_degrees():
    # the ideal case: both are (n + sqrt(fn)) / (f - n) = 11/99
    assert float(W.lambda_gmnpr(math.pi / 2, PHI, N, F)) == pytest.approx(11 / 99, rel=1e-12)
    assert float(W.lambda_lispsm(math.pi / 2, PHI, N, F)) == pytest.approx(11 / 99, rel=1e-12)


def test_gmnpr_lambda_is_continuous_at_phi():
    """No jump at phi, only a kink: across phi +- eps the difference shrinks with eps (at
    eps = 1e-6 it is 1.6e-6 relative, the slopes of lambda_1 and lambda_2* times eps)."""
    at = float(W.lambda_gmnpr(PHI, PHI, N, F))
    assert at == pytest.approx(math.sqrt(F * N) / (2 * F), rel=1e-12)  # equation 7 at phi
    for eps in (1e-4, 1e-6, 1e-8):
        below, above = (float(W.lambda_gmnpr(PHI + d, PHI, N, F)) for d in (-eps, eps))
        assert abs(above - below) / at < 2 * eps
    below, above = (float(W.lambda_gmnpr(PHI + d, PHI, N, F)) for d in (-1e-9, 1e-9))
    assert abs(above - below) / at < 1e-6


def test_figure_5_lambda_against_theta():
    thetas = np.radians(np.arange(1, 91))
    gmnpr = W.lambda_gmnpr(thetas, PHI, N, F)
    plain = W.lambda_minimum_norm(thetas, PHI, N, F)
    assert np.all(gmnpr > 0)
    assert np.all(np.diff(gmnpr[thetas >= PHI]) > 0)  # decreases from pi/2 down to phi
    assert np.all(np.diff(gmnpr[thetas <= PHI]) < 0)  # grows again below phi (toward the SM)
    assert float(W.lambda_gmnpr(1e-9, PHI, N, F)) > 1e6
    # equation 4 below phi plunges through zero: why lambda_2* replaces it
    assert float(W.lambda_minimum_norm(math.radians(5), PHI, N, F)) < 0
    assert plain[thetas >= PHI] == pytest.approx(gmnpr[thetas >= PHI], rel=1e-12)


def test_figure_6_minimum_norm_property():
    """F(n) = F(f) for GMNPR at every theta >= phi; for LiSPSM only at 90 degrees."""
    lispsm_ratio = []
    for theta_deg in [90.0, 85.0, 70.0, 55.0, 40.0, 30.0]:
        theta = math.radians(theta_deg)
        for choose, name in [(W.lambda_gmnpr, "gmnpr"), (W.lambda_lispsm, "lispsm")]:
            lam = float(choose(theta, PHI, N, F))
            near, far = (float(W.aliasing_F(lam, theta, z, PHI, N, F)) for z in (N, F))
            z = np.linspace(N, F, 2001)
            inner = W.aliasing_F(lam, theta, z, PHI, N, F)
            assert inner.max() <= max(near, far) * (1 + 1e-9)  # the maxima are at the ends
            if name == "gmnpr" or theta_deg == 90.0:
                assert near == pytest.approx(far, rel=1e-9), (name, theta_deg)
            else:
                assert near > far * 1.01, (name, theta_deg)
            if name == "lispsm":
                lispsm_ratio.append(near / far)
    assert np.all(np.diff(lispsm_ratio) > 0)  # LiSPSM's near errors grow as theta decreases


# --- random cameras and lights ------------------------------------------------------------


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def perspective(yfov, aspect, near, far):
    f = 1 / math.tan(yfov / 2)
    return np.array([[f / aspect, 0, 0, 0], [0, f, 0, 0],
                     [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
                     [0, 0, -1, 0]])


vectors = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1)


@st.composite
def configurations(draw):
    eye = np.array(draw(st.tuples(*[st.floats(-20, 20)] * 3)))
    forward = unit(draw(vectors))
    up = unit(draw(vectors))
    if np.linalg.norm(np.cross(forward, up)) < 0.1:
        up = np.eye(3)[np.argmin(np.abs(forward))]
    near = draw(st.sampled_from([0.01, 0.1, 1.0]))
    far = near * draw(st.sampled_from([10.0, 100.0, 1e5]))
    yfov = math.radians(draw(st.floats(20, 100)))
    aspect = draw(st.floats(0.5, 2.0))
    light_kind = draw(st.sampled_from(["random", "parallel", "antiparallel", "perpendicular"]))
    light = unit(draw(vectors))
    if light_kind == "parallel":
        light = forward
    elif light_kind == "antiparallel":
        light = -forward
    elif light_kind == "perpendicular":
        light = unit(light - (light @ forward) * forward) if np.linalg.norm(
            light - (light @ forward) * forward) > 1e-3 else unit(np.cross(forward, up))
    centre = eye + forward * draw(st.floats(0, 30)) + np.array(draw(st.tuples(*[st.floats(-5, 5)] * 3)))
    half = np.array(draw(st.tuples(*[st.floats(1, 40)] * 3)))
    half[draw(st.integers(0, 3)) % 3] *= draw(st.sampled_from([0.0, 1.0]))  # flat scenes too
    bounds = np.stack([centre - half, centre + half])
    view = look_at(eye, eye + forward, up)
    setup = W.ViewSetup(view, perspective(yfov, aspect, near, far), eye, forward, light,
                        near, far, bounds, W.ReceiverPoints(np.empty((0, 3))))
    return setup, draw(st.integers(0, 2**31 - 1))


def visible_samples(setup, seed, count=400):
    """Random points of the scene box inside the view frustum (where receivers can be)."""
    rng = np.random.default_rng(seed)
    b = setup.bounds
    points = b[0] + rng.random((count * 20, 3)) * (b[1] - b[0])
    clip = np.hstack([points, np.ones((len(points), 1))]) @ setup.view_proj.T
    inside = (clip[:, 3] > 0) & np.all(np.abs(clip[:, :3]) <= clip[:, 3:] * (1 - 1e-6), axis=1)
    return points[inside][:count]


def to_clip(clip, points):
    return np.hstack([points, np.ones((len(points), 1))]) @ clip.T


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(configurations())
def test_random_configurations_matrix_properties(case):
    """Over random cameras, lights and scene boxes, with random visible receivers (or none):
    finite matrices; every receiver inside each map's unit cube (PSM's after its fallback); a
    texel is one light ray and depth grows along it; PSM's virtual camera sees the whole body
    (casters included) in front of its near plane, slid back no further than needed."""
    setup, seed = case
    points = visible_samples(setup, seed)
    setup = dataclasses.replace(setup, receivers=W.ReceiverPoints(points))
    for choose in (W.lispsm_eye_distance, W.gmnpr_eye_distance):
        warp = W.light_space_warp(setup, 256, choose)
        assert metrics.nonfinite(warp.clip, warp.frustum.view, warp.frustum.proj) == 0
        assert 0 < warp.lam <= W.LAMBDA_MAX
        # the map is the frustum's view and proj: their product is the warp
        assert np.allclose(warp.frustum.proj @ warp.frustum.view, warp.clip, rtol=1e-9,
                           atol=1e-9 * np.abs(warp.clip).max())
        if len(points) == 0:
            continue
        c = to_clip(warp.clip, points)
        w = c[:, 3]
        assert np.all(w > 0)
        assert np.all(np.abs(c[:, :3]) <= w[:, None] * (1 + 1e-6))  # inside the unit cube
        # a texel is one light ray, and depth grows along the light's travel
        step = 0.01 * np.linalg.norm(setup.bounds[1] - setup.bounds[0])
        moved = to_clip(warp.clip, points + step * setup.light)
        scale = np.abs(c[:, :2] / w[:, None]).max() + 1
        assert np.allclose(moved[:, :2] / moved[:, 3:], c[:, :2] / w[:, None], atol=1e-7 * scale)
        assert np.all(moved[:, 2] / moved[:, 3] > c[:, 2] / w)
    psm = W.post_perspective_warp(setup, 256)
    assert metrics.nonfinite(psm.clip, psm.frustum.proj) == 0
    assert psm.slide_back >= 0
    virtual_depth = to_clip(psm.camera, W.light_space(setup).world_body)[:, 3]
    assert virtual_depth.min() >= setup.near * (1 - 1e-9)
    if psm.slide_back > 0:
        assert virtual_depth.min() == pytest.approx(setup.near, rel=1e-9)
    if len(points):
        assert not W.outside_unit_cube(psm.clip, points, np.ones(len(points), bool)).any()
