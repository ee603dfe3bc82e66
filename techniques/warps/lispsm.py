"""Light space perspective shadow maps (Wimmer, Scherzer, Purgathofer 2004)."""

from __future__ import annotations

from .warp_body import ViewSetup
from .warp_equations import lispsm_eye_distance
from .warp_fit import light_space_warp, warp_columns
from .warped_map import PARAMETER_TABLE, WarpedShadowMap


class LightSpacePerspectiveShadowMap(WarpedShadowMap):
    __doc__ = """A perspective warp in light space along the view direction projected
    perpendicular to the light, so the light stays directional after it.

    The warp frustum's eye sits n_opt = (n + sqrt(n f)) / sin(theta) before the body along the
    warp axis (P_n of equation 9 of Zhang et al.; where Wimmer et al.'s code and
    OpenSceneGraph put it), n and f the nearest and farthest view depth of the visible
    receivers; its lambda is n_opt over the body's actual depth along the warp axis, clamped to
    LAMBDA_MAX near theta = 0 where n_opt is infinite. A spot light is warped in its
    post-projective space, as the authors' code does, with theta, n and f measured there; with
    the camera behind the spot light's plane the map is not warped. Shaded by
    ``warp_shading.frag.glsl``. Columns: ``theta_deg``, ``lambda``, ``n_opt``,
    ``warp_eye_distance`` (equal to ``n_opt`` unless clamped), ``depth_near``, ``depth_far``
    (n and f), ``alias_mean``, ``alias_max``, ``alias_near``, ``outside_pct``.
    """ + PARAMETER_TABLE

    name = "lispsm"
    colour = "#17becf"
    summary = "light space perspective shadow map: warp in light space, n_opt near distance"
    paper = "Wimmer, Scherzer, Purgathofer 2004, Light space perspective shadow maps"
    # quality knob: the map size (the warp is fixed by the view), in factor-4 steps that keep
    # make bench within its 10 minutes
    quality_knobs = {"res": (256, 1024, 4096)}

    def warp(self, setup: ViewSetup, res: int):
        warp = light_space_warp(setup, res, lispsm_eye_distance)
        return warp, warp_columns(warp)
