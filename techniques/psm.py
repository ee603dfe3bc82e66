"""Perspective shadow maps (Stamminger, Drettakis 2002)."""

from __future__ import annotations

from .warping import PARAMETER_TABLE, ViewSetup, WarpedShadowMap, post_perspective_warp


class PerspectiveShadowMap(WarpedShadowMap):
    __doc__ = """The map is rendered in the camera's post-perspective space, where the
    directional light becomes a point light (an inverted one when it is behind the viewer,
    a directional one when it is perpendicular to the view).

    The virtual camera slides back until every caster of the visible receivers is in front of
    it; the light frustum is fitted to the receivers there (unit-cube clipping). Its known
    failure, a light whose post-perspective point lies among the receivers (the light in front
    of the viewer inside the view), is measured in ``outside_pct``, not hidden. Directional
    lights only; shaded by ``warp_shading.frag.glsl``. Columns: ``theta_deg``, ``slide_back``,
    ``light_kind``, ``alias_mean``, ``alias_max``, ``outside_pct``.
    """ + PARAMETER_TABLE

    name = "psm"
    summary = "perspective shadow map: the map made in the camera's post-perspective space"
    paper = "Stamminger, Drettakis 2002, Perspective shadow maps"
    # quality knob: the map size (the warp is fixed by the view), in factor-4 steps that keep
    # make bench within its 10 minutes
    quality_knobs = {"res": (256, 1024, 4096)}

    def warp(self, setup: ViewSetup, res: int):
        warp = post_perspective_warp(setup, res)
        return warp, dict(slide_back=warp.slide_back, light_kind=warp.light_kind)
