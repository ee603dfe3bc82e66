"""Generalized minimum-norm perspective reparameterization (Zhang, Sun, Zhao, Wang 2007)."""

from __future__ import annotations

from .warping import PARAMETER_TABLE, ViewSetup, WarpedShadowMap, lambda_gmnpr, light_space_warp


class GeneralizedMinimumNormWarp(WarpedShadowMap):
    __doc__ = """LiSPSM's light-space warp with the warp strength lambda of equation 8: the
    minimum-norm lambda_1 (perspective aliasing equal at the near and far planes) for theta in
    [phi, pi/2], and lambda_1(phi) / tan(pi theta / (4 phi)) below phi, continuous at phi and
    growing to the standard shadow map at theta = 0.

    theta is the angle between light and view, phi the frustum's half angle toward the light,
    n and f the view depths of the view frustum clipped to the scene. Directional lights only;
    shaded by ``warp_shading.frag.glsl``. Columns: ``theta_deg``, ``lambda``, ``alias_mean``,
    ``alias_max``, ``outside_pct``.
    """ + PARAMETER_TABLE

    name = "gmnpr"
    summary = "generalized minimum-norm perspective shadow map: lambda keeps F(n) = F(f)"
    paper = ("Zhang, Sun, Zhao, Wang 2007, Generalized minimum-norm perspective shadow maps "
             "for anti-aliased shadow rendering in 3D computer games")
    # quality knob: the map size (the warp is fixed by the view), in factor-4 steps that keep
    # make bench within its 10 minutes
    quality_knobs = {"res": (256, 1024, 4096)}

    def warp(self, setup: ViewSetup, res: int):
        warp = light_space_warp(setup, res, lambda_gmnpr)
        return warp, {"lambda": warp.lam}
