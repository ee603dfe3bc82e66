"""The papers' formulas in their 2-D model (n, f view depths, phi the half field of view):
lambda (Zhang et al.'s equations 4, 8, 9), Wimmer et al.'s n_opt, the aliasing F (equation 2).

The equations are those of Zhang et al., "Generalized Minimum-Norm Perspective Shadow Maps";
each light-space technique's warp-frustum eye distance is built from them.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

# lambda is clamped here: at theta = 0 both LiSPSM's and GMNPR's lambda are infinite (the
# standard shadow map); 1e4 body depths of warp distance is indistinguishable from it.
LAMBDA_MAX = 1.0e4


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


def n_opt(theta, n, f):
    """LiSPSM's warp-frustum near distance P_n = (n + sqrt(f n)) / sin(theta) (equation 9's
    numerator; Wimmer et al.'s n_opt), infinite at theta = 0."""
    with np.errstate(divide="ignore"):
        return (n + math.sqrt(f * n)) / np.sin(np.asarray(theta, dtype=np.float64))


def lambda_lispsm(theta, phi, n, f):
    """Equation 9: n_opt over the body depth P_f - P_n of the paper's 2-D model."""
    theta = np.maximum(np.asarray(theta, dtype=np.float64), 1e-300)
    t = math.tan(phi) / np.tan(theta)
    depth = np.where(theta >= phi, (f - n + (f + n) * t) * np.sin(theta),
                     2 * f * math.tan(phi) * np.cos(theta))
    return n_opt(theta, n, f) / depth


def aliasing_F(lam, theta, z, phi, n, f):
    """Equation 2: perspective aliasing F(lambda, theta, z) = psi (z + varphi)^2 / z."""
    lam, theta, z = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (lam, theta, z)))
    t = math.tan(phi) / np.tan(np.maximum(theta, 1e-300))
    a = f - n + (f + n) * t
    psi = np.where(theta >= phi, 1 / (math.tan(phi) * a * lam * (lam + 1)),
                   1 / (math.tan(phi) * 2 * f * lam * (lam + 1) / t))
    varphi = np.where(theta >= phi, a * lam + n * t - n, f * (2 * lam + 1) * t - f)
    return psi * (z + varphi) ** 2 / z


# The warp-frustum eye distance P_n of each light-space technique, in the units of the space the
# warp is made in, from theta, phi, the view depths n and f, and the body's depth along the warp
# axis: LiSPSM puts it at n_opt (Wimmer et al.'s code and OpenSceneGraph's
# LightSpacePerspectiveShadowMap do), GMNPR at lambda body depths (its lambda is for a
# normalised depth range P_f - P_n = 1).
EyeDistance = Callable[[float, float, float, float, float], float]


def lispsm_eye_distance(theta, phi, n, f, depth):
    return float(n_opt(theta, n, f))


def gmnpr_eye_distance(theta, phi, n, f, depth):
    return float(lambda_gmnpr(theta, phi, n, f)) * depth
