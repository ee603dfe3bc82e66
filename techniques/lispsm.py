"""Light space perspective shadow maps (Wimmer, Scherzer, Purgathofer 2004)."""

from __future__ import annotations

from .warping import PARAMETER_TABLE, ViewSetup, WarpedShadowMap, lambda_lispsm, light_space_warp


class LightSpacePerspectiveShadowMap(WarpedShadowMap):
    __doc__ = """A perspective warp in light space along the view direction projected
    perpendicular to the light, so the light stays directional after it.

    The warp frustum's eye sits n_opt = (z_n + sqrt(z_n z_f)) / sin(gamma) before the body,
    i.e. lambda = n_opt / (body depth along the warp axis), equation 9 of Zhang et al.; z_n and
    z_f are the view depths of the view frustum clipped to the scene. Directional lights only;
    shaded by ``warp_shading.frag.glsl``. Columns: ``theta_deg``, ``lambda``, ``alias_mean``,
    ``alias_max``, ``outside_pct``.
    """ + PARAMETER_TABLE

    name = "lispsm"
    summary = "light space perspective shadow map: warp in light space, n_opt near distance"
    paper = "Wimmer, Scherzer, Purgathofer 2004, Light space perspective shadow maps"
    # quality knob: the map size (the warp is fixed by the view), in factor-4 steps that keep
    # make bench within its 10 minutes
    quality_knobs = {"res": (256, 1024, 4096)}

    def warp(self, setup: ViewSetup, res: int):
        warp = light_space_warp(setup, res, lambda_lispsm)
        return warp, {"lambda": warp.lam}
