"""Perspective shadow maps (Stamminger, Drettakis 2002)."""

from __future__ import annotations

from .warp_body import ViewSetup
from .warp_fit import post_perspective_warp
from .warped_map import PARAMETER_TABLE, WarpedShadowMap


class PerspectiveShadowMap(WarpedShadowMap):
    __doc__ = """The map is rendered in the camera's post-perspective space, where the light (a
    directional light, or a spot light's point, as the paper treats both) becomes a point light
    (an inverted one when it is behind the viewer, a directional one when it lies in the
    camera's plane).

    The virtual camera slides back until every caster of the visible receivers is in front of
    it; the light frustum is fitted to the receivers there (unit-cube clipping). Where that map
    still cannot hold every visible receiver (some fall outside its unit cube or behind the
    post-perspective light: a light behind the viewer nearly along the view direction, or one in
    front of the viewer whose post-perspective point lies among the receivers), the run falls
    back to the unwarped map (orthographic along a directional light, the spot light's own
    perspective) fitted to the same body, and ``fallback`` says so; ``outside_pct`` then
    measures that map. Shaded by ``warp_shading.frag.glsl``. Columns: ``theta_deg``,
    ``slide_back``, ``light_kind``, ``fallback``, ``alias_mean``, ``alias_max``,
    ``alias_near``, ``outside_pct``.
    """ + PARAMETER_TABLE

    name = "psm"
    colour = "#bcbd22"
    summary = "perspective shadow map: the map made in the camera's post-perspective space"
    paper = "Stamminger, Drettakis 2002, Perspective shadow maps"
    # quality knob: the map size (the warp is fixed by the view), in factor-4 steps that keep
    # make bench within its 10 minutes
    quality_knobs = {"res": (256, 1024, 4096)}

    def warp(self, setup: ViewSetup, res: int):
        warp = post_perspective_warp(setup, res)
        return warp, dict(slide_back=warp.slide_back, light_kind=warp.light_kind,
                          fallback=warp.fallback)
