"""Generalized minimum-norm perspective reparameterization (Zhang, Sun, Zhao, Wang 2007)."""

from __future__ import annotations

from harness.technique import NotApplicable

from .warp_body import ViewSetup
from .warp_equations import gmnpr_eye_distance
from .warp_fit import light_space_warp, warp_columns
from .warped_map import PARAMETER_TABLE, WarpedShadowMap


class GeneralizedMinimumNormWarp(WarpedShadowMap):
    __doc__ = """LiSPSM's light-space warp with the warp strength lambda of equation 8: the
    minimum-norm lambda_1 (perspective aliasing equal at the near and far planes) for theta in
    [phi, pi/2], and lambda_1(phi) / tan(pi theta / (4 phi)) below phi, continuous at phi and
    growing to the standard shadow map at theta = 0. The warp frustum's eye sits lambda body
    depths (along the warp axis) before the body.

    theta is the angle between light and view, phi the frustum's half angle toward the light,
    n and f the nearest and farthest view depth of the visible receivers. Directional lights
    only: the paper's aliasing model (equation 2) assumes one and it leaves other lights to
    further work. Shaded by ``warp_shading.frag.glsl``. Columns: ``theta_deg``, ``lambda``,
    ``warp_eye_distance`` (lambda x body depth), ``n_opt`` (LiSPSM's, for comparison),
    ``depth_near``, ``depth_far`` (n and f), ``alias_mean``, ``alias_max``, ``alias_near``,
    ``outside_pct``.
    """ + PARAMETER_TABLE

    name = "gmnpr"
    colour = "#000000"
    summary = "generalized minimum-norm perspective shadow map: lambda keeps F(n) = F(f)"
    paper = ("Zhang, Sun, Zhao, Wang 2007, Generalized minimum-norm perspective shadow maps "
             "for anti-aliased shadow rendering in 3D computer games")
    # quality knob: the map size (the warp is fixed by the view), in factor-4 steps that keep
    # make bench within its 10 minutes
    quality_knobs = {"res": (256, 1024, 4096)}

    def warp(self, setup: ViewSetup, res: int):
        if setup.spot is not None:
            raise NotApplicable("GMNPR's paper treats directional lights only (its aliasing model, "
                                "equation 2, assumes one), not a spot light")
        warp = light_space_warp(setup, res, gmnpr_eye_distance)
        return warp, warp_columns(warp)
