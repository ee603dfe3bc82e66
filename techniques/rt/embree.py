"""``backend: embree``: rt's rays on the CPU through Mitsuba's ``ray_test``, the tracer the
reference uses (Embree in its CPU variants), on the scene the reference builds
(``harness.truth.reference.mitsuba_scene_dict``: the same triangles, moved next to Mitsuba's origin).
The G-buffer read-back, the trace and the upload of the mask are timed passes; the scene build
is ``prepare``'s. The parts of objects the scene's motion moves are Mitsuba instances of shape
groups (Embree's two levels): a frame moves them by their poses in the timed ``tlas`` pass,
as the compute traversal's top level, and nothing is built again."""

from __future__ import annotations

import numpy as np
from OpenGL import GL

from harness.truth import reference

# common/ray_offset.glsl's rule, the same constants
OFFSET_ULPS, ORIGIN, FLOAT_SCALE = 256, 1.0 / 32.0, 1.0 / 65536.0


def offset_ray(p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``common/ray_offset.glsl``'s ``offset_ray`` on float32 arrays (..., 3): the same bits."""
    p, n = np.asarray(p, np.float32), np.asarray(n, np.float32)
    step = (np.float32(OFFSET_ULPS) * n).astype(np.int32)  # truncates as GLSL's int()
    moved = (p.view(np.int32) + np.where(p < 0, -step, step)).view(np.float32)
    return np.where(np.abs(p) < ORIGIN, p + np.float32(FLOAT_SCALE) * n, moved)


def shadow_rays(position, normal, directional: bool, light, camera_position):
    """Which points (float32 (N, 3), with normals) the light reaches (their visible side, the
    normal turned to the camera, faces it: ``rt_trace.comp.glsl``'s test), and the shadow rays
    from those: origins offset along that normal, unit directions toward the light, lengths."""
    light = np.asarray(light, np.float64)
    to_camera = np.asarray(camera_position, np.float64) - position
    normal = np.where((np.sum(normal * to_camera, axis=1) >= 0)[:, None], normal, -normal)
    to_light = np.broadcast_to(light, position.shape) if directional else light - position
    facing = np.sum(normal * to_light, axis=1) > 0
    position, normal = position[facing], normal[facing]
    origin = offset_ray(position, normal)
    direction = np.broadcast_to(light, origin.shape) if directional else light - origin
    length = np.linalg.norm(direction, axis=1)
    maxt = np.full(len(origin), np.inf) if directional else length
    return facing, origin, direction / np.maximum(length, 1e-30)[:, None], maxt


def moving_parts(frame) -> list[int]:
    """The parts of the objects the frame's motion moves (none on a still scene)."""
    scene = frame.sequence.config
    if not scene.motion:
        return []
    movers = {scene.object_index(path.object) for path in scene.motion.objects}
    return [i for i, part in enumerate(frame.scene.parts) if part.object_index in movers]


class EmbreeRays:
    """Mitsuba's scene of ``frame``'s (at frame 0), moving parts as instances."""

    def __init__(self, frame):
        mi = self.mi = reference.mitsuba_module(reference.choose_variant())
        self.shift = reference.mitsuba_origin(frame.scene)
        self.moving = moving_parts(frame)
        d = reference.mitsuba_scene_dict(frame.scene, mi, samples=1)
        for i in self.moving:
            d[f"group{i}"] = {"type": "shapegroup", "mesh": d.pop(f"mesh{i}")}
            d[f"instance{i}"] = {"type": "instance",
                                 "shapegroup": {"type": "ref", "id": f"group{i}"}}
        self.scene = mi.load_dict(d)
        self.params = mi.traverse(self.scene) if self.moving else None
        self.poses = np.tile(np.eye(4), (len(self.moving), 1, 1))

    def follow(self, frame) -> None:
        """Move the instances to the frame's poses, where they changed, in the timed ``tlas``
        pass: Mitsuba updates its top level (each pose taken into Mitsuba's coordinates, the
        scene moved by ``-shift``)."""
        poses = frame.part_poses[self.moving]
        if np.array_equal(poses, self.poses):
            return
        with frame.measure("tlas"):
            to_shifted, from_shifted = np.eye(4), np.eye(4)
            to_shifted[:3, 3], from_shifted[:3, 3] = -self.shift, self.shift
            for i, pose in zip(self.moving, poses):
                self.params[f"instance{i}.to_world"] = self.mi.Transform4f(
                    (to_shifted @ pose @ from_shifted).tolist())
            self.params.update()
        self.poses = poses

    def trace(self, frame, mask, divisor: int, light: dict, camera_position) -> None:
        """The mask (GL rows, bottom first) from one ray per mask texel (V = 0 and no ray
        where the visible side faces away from the light)."""
        mi = self.mi
        with frame.measure("readback"):
            g = frame.gbuffer.read()
        with frame.measure("trace"):
            h, w = g.covered.shape
            rows = np.minimum(np.arange(mask.height) * divisor + divisor // 2, h - 1)
            cols = np.minimum(np.arange(mask.width) * divisor + divisor // 2, w - 1)
            pick = np.ix_(h - 1 - rows, cols)  # GL row y is the image's row h - 1 - y
            covered = g.covered[pick]
            facing, origin, direction, maxt = shadow_rays(
                g.position[pick][covered], g.normal[pick][covered], light["directional"],
                light["light"], camera_position)
            hit = np.zeros(len(origin), bool)
            if len(origin):  # Dr.Jit aborts the process on a trace of no rays
                o = (origin.astype(np.float64) - self.shift).astype(np.float32)
                ray = mi.Ray3f(mi.Point3f(*o.T), mi.Vector3f(*direction.astype(np.float32).T))
                ray.maxt = mi.Float(maxt.astype(np.float32))
                hit = np.asarray(self.scene.ray_test(ray), bool)
            lit = np.zeros(int(covered.sum()), np.float32)
            lit[facing] = np.where(hit, 0.0, 1.0)
            v = np.ones(covered.shape, np.float32)
            v[covered] = lit
        with frame.measure("upload"):
            GL.glBindTexture(GL.GL_TEXTURE_2D, mask.id)
            GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
            GL.glTexSubImage2D(GL.GL_TEXTURE_2D, 0, 0, 0, mask.width, mask.height, GL.GL_RED,
                               GL.GL_FLOAT, np.ascontiguousarray(v))
            GL.glBindTexture(GL.GL_TEXTURE_2D, 0)

    def release(self) -> None:
        self.scene = None
