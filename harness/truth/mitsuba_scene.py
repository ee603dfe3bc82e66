"""The scene as Mitsuba takes it: the same triangles as the GL side's (moved next to Mitsuba's
origin), the matched camera, the delta light; cut-out parts with their texture coordinates per
face corner and every mesh with its cut-out's index (harness.truth.cutouts)."""

from __future__ import annotations

import math

import numpy as np

from ..scene import BuiltScene
from .cutouts import CUTOUT_ATTRIBUTE, jit_variant

# Irradiance (directional) or intensity (spot, point) of pi makes the diffuse radiance
# albedo * cos (/ r^2 for a positional light), the same scale the GL side shades with.
LIGHT_POWER = math.pi


def _mesh(mi, name: str, vertices: np.ndarray, faces: np.ndarray, albedo: float,
          texcoords: np.ndarray | None = None, cutout: int | None = None):
    """A Mitsuba mesh of these triangles. In a scene with cut-outs (``cutout`` given: the
    index of the part's mask in ``scene.alpha_masks``, -1 for an opaque part) it carries the
    per-face attribute ``face_cutout``, and a cut-out part its texture coordinates per vertex
    (``texcoords`` (V, 2): its vertices unrolled per face corner by the caller)."""
    mesh = mi.Mesh(name, len(vertices), len(faces), has_vertex_normals=False,
                   has_vertex_texcoords=texcoords is not None)
    params = mi.traverse(mesh)
    arrays = [("vertex_positions", np.asarray(vertices, np.float32)),
              ("faces", np.asarray(faces, np.uint32))]
    if texcoords is not None:
        arrays.append(("vertex_texcoords", np.asarray(texcoords, np.float32)))
    # the buffers' own types: mi.Float in the JIT variants, dynamic arrays in scalar ones
    for key, array in arrays:
        params[key] = type(params[key])(np.ascontiguousarray(array).ravel())
    params.update()
    if cutout is not None:
        column = np.full(len(faces), cutout, np.float32)
        mesh.add_attribute(CUTOUT_ATTRIBUTE, 1, mi.Float(column) if jit_variant(mi) else
                           column.tolist())
    mesh.set_bsdf(mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb",
                                                                   "value": [albedo] * 3}}))
    return mesh


def mitsuba_origin(scene: BuiltScene) -> np.ndarray:
    """Where Mitsuba's world origin sits in scene coordinates: the centre of the bounds.

    Mitsuba traces in float32 and offsets shadow rays by an epsilon relative to the magnitude
    of the coordinates; around 1e5 that offset reaches a scene unit and shadows go missing.
    Visibility is translation invariant, so the reference traces the scene moved next to the
    origin (the same float32 vertices, shifted in float64 exactly).
    """
    return np.round(scene.bounds.mean(axis=0))


def mitsuba_scene_dict(scene: BuiltScene, mi, samples: int, seed: int = 0) -> dict:
    """The scene for Mitsuba: the same meshes, the matched camera, the delta light,
    translated by ``-mitsuba_origin(scene)``."""
    cam = scene.config.camera
    origin = mitsuba_origin(scene)
    d: dict = {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": cam.yfov,
            "near_clip": cam.near,
            "far_clip": cam.far,
            "to_world": mi.ScalarTransform4f().look_at(
                origin=(np.asarray(cam.position) - origin).tolist(),
                target=(np.asarray(cam.target) - origin).tolist(), up=cam.up),
            "film": {"type": "hdrfilm", "width": scene.width, "height": scene.height,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "stratified", "sample_count": samples, "seed": seed},
        },
    }
    light = scene.light
    intensity = {"type": "rgb", "value": [LIGHT_POWER * light.power_scale] * 3}
    if light.type == "directional":
        d["light"] = {"type": "directional", "direction": light.direction.tolist(),
                      "irradiance": {"type": "rgb", "value": [LIGHT_POWER] * 3}}
    elif light.type == "point":
        d["light"] = {"type": "point", "position": (light.position - origin).tolist(),
                      "intensity": intensity}
    else:
        half = light.fov_deg / 2
        d["light"] = {
            "type": "spot", "cutoff_angle": half, "beam_width": half, "intensity": intensity,
            "to_world": mi.ScalarTransform4f().look_at(
                origin=(light.position - origin).tolist(),
                target=(light.position - origin + light.direction).tolist(),
                up=_up_for(light.direction).tolist()),
        }
    masks = {id(m): k for k, m in enumerate(scene.alpha_masks)}
    for i, part in enumerate(scene.parts):
        vertices = part.vertices.astype(np.float64) - origin
        if not scene.has_alpha:  # as before cut-outs: the opaque scenes' path, unchanged
            d[f"mesh{i}"] = _mesh(mi, f"mesh{i}", vertices, part.faces, part.albedo)
        elif part.alpha is None:
            d[f"mesh{i}"] = _mesh(mi, f"mesh{i}", vertices, part.faces, part.albedo, cutout=-1)
        else:  # unrolled: texture coordinates are per face corner
            d[f"mesh{i}"] = _mesh(mi, f"mesh{i}", vertices[part.faces].reshape(-1, 3),
                                  np.arange(3 * len(part.faces)).reshape(-1, 3), part.albedo,
                                  part.texcoords.reshape(-1, 2), masks[id(part.alpha)])
    return d


def _up_for(direction: np.ndarray) -> np.ndarray:
    from ..scene.transforms import any_perpendicular_up

    return any_perpendicular_up(direction)
