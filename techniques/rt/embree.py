"""``backend: embree``: rt's rays on the CPU through Mitsuba's ``ray_test``, the tracer the
reference uses (Embree in its CPU variants), on the scene the reference builds
(``harness.truth.mitsuba_scene.mitsuba_scene_dict``: the same triangles, moved next to Mitsuba's origin).
The G-buffer read-back, the trace and the upload of the mask are timed passes; the scene build
is ``prepare``'s. The parts of objects the scene's motion moves are Mitsuba instances of shape
groups (Embree's two levels): a frame moves them by their poses in the timed ``tlas`` pass,
as the compute traversal's top level, and nothing is built again.

On a scene with alpha-tested casters ``ray_test`` (which stops at any triangle) gives way to
an any-hit loop of ``ray_intersect_preliminary``: a hit on a cut-out texel (its face's texture
coordinates at the hit's barycentrics, by harness.scene.alpha's rule) moves the ray's origin
just past it, at most ``MAX_CUTOUT_HITS`` times (beyond, the cut-outs left count as
opaque)."""

from __future__ import annotations

import numpy as np
from OpenGL import GL

from harness.technique import NotApplicable
from harness.truth import reference

# common/ray_offset.glsl's rule, the same constants
OFFSET_ULPS, ORIGIN, FLOAT_SCALE = 256, 1.0 / 32.0, 1.0 / 65536.0
# cut-out hits one ray passes before the rest count as opaque
MAX_CUTOUT_HITS = 64


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
        if frame.scene.has_alpha and any(frame.scene.parts[i].alpha for i in self.moving):
            raise NotApplicable("rt backend embree does not treat moving alpha-tested casters "
                                "(its hits in Mitsuba's instances are not named by part); "
                                "backend gl does")
        self.scene = mi.load_dict(d)
        self.params = mi.traverse(self.scene) if self.moving else None
        self.poses = np.tile(np.eye(4), (len(self.moving), 1, 1))
        self.cutouts = _Cutouts(mi, self.scene, frame.scene) if frame.scene.has_alpha else None

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

    def trace(self, frame, mask, divisor: int, light: dict, camera_position) -> dict:
        """The mask (GL rows, bottom first) from one ray per mask texel (V = 0 and no ray
        where the visible side faces away from the light). Returns what the rays counted:
        on a scene with cut-outs, ``alpha_tests_per_ray`` (the any-hit loop's alpha tests)."""
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
            hit, counted = np.zeros(len(origin), bool), {}
            if len(origin):  # Dr.Jit aborts the process on a trace of no rays
                o = (origin.astype(np.float64) - self.shift).astype(np.float32)
                if self.cutouts is None:
                    hit = self._ray_test(o, direction, maxt)
                else:
                    hit, tests = self.cutouts.any_hit(self._ray_test, o, direction, maxt)
                    counted["alpha_tests_per_ray"] = round(tests / len(origin), 3)
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
        return counted

    def _ray_test(self, origin, direction, maxt) -> np.ndarray:
        """Whether each ray (float32 (N, 3) origins in Mitsuba's coordinates, unit
        directions, lengths) meets any triangle."""
        return np.asarray(self.scene.ray_test(mitsuba_rays(self.mi, origin, direction, maxt)),
                          bool)

    def release(self) -> None:
        self.scene = self.cutouts = None


def mitsuba_rays(mi, origin, direction, maxt):
    """Mitsuba's rays (float32) from arrays (N, 3), (N, 3), (N,)."""
    ray = mi.Ray3f(mi.Point3f(*np.asarray(origin, np.float32).T),
                   mi.Vector3f(*np.asarray(direction, np.float32).T))
    ray.maxt = mi.Float(np.asarray(maxt, np.float32))  # the third argument would be the time
    return ray


class _Cutouts:
    """What the any-hit loop reads of a scene with cut-outs (``scene``, loaded as Mitsuba's
    ``mscene``): each Mitsuba shape's part, the parts' first faces, every face's texture
    coordinates and cut-out."""

    def __init__(self, mi, mscene, scene):
        import drjit as dr

        self.mi, self.dr, self.mscene = mi, dr, mscene
        ids = {int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]): s.id()
               for s in mscene.shapes()}
        self.part_of = np.full(max(ids, default=0) + 1, -1, np.int64)  # by Mitsuba's shape id
        for shape_id, name in ids.items():
            if name.startswith("mesh"):
                self.part_of[shape_id] = int(name[4:])
        self.first_face = np.cumsum([0] + [len(p.faces) for p in scene.parts])
        self.masks, self.face_mask = scene.alpha_masks, scene.face_mask
        self.texcoords = scene.face_texcoords.astype(np.float64)
        self.normals = scene.face_normals

    def any_hit(self, ray_test, origin, direction, maxt) -> tuple[np.ndarray, int]:
        """Whether each ray meets a triangle where it is not cut out (``ray_test``: the
        opaque test, for the rays left after MAX_CUTOUT_HITS cut-out hits), and the alpha
        tests made."""
        mi, dr = self.mi, self.dr
        hit, tests = np.zeros(len(origin), bool), 0
        rays = np.arange(len(origin))
        origin, maxt = np.asarray(origin, np.float32), np.asarray(maxt, np.float64)
        for _ in range(MAX_CUTOUT_HITS):
            o, d = origin[rays], direction[rays]
            pi = self.mscene.ray_intersect_preliminary(mitsuba_rays(mi, o, d, maxt[rays]))
            shape = dr.reinterpret_array(mi.UInt32, pi.shape)
            dr.eval(pi.t, pi.prim_index, pi.prim_uv, shape)  # one kernel, not one per read
            valid = np.isfinite(np.asarray(pi.t, np.float64))
            shape = np.asarray(shape, np.int64)
            part = np.where(valid, self.part_of[np.minimum(shape, len(self.part_of) - 1)], -1)
            face = self.first_face[np.maximum(part, 0)] + np.asarray(pi.prim_index, np.int64)
            mask = np.where(part >= 0, self.face_mask[np.where(part >= 0, face, 0)], -1)
            b = np.asarray(pi.prim_uv, np.float64).T.reshape(-1, 2)
            weights = np.column_stack([1.0 - b.sum(axis=1), b])
            cut = np.zeros(len(rays), bool)
            tests += int(np.count_nonzero(mask >= 0))
            for m in np.unique(mask[mask >= 0]):
                sel = mask == m
                uv = np.einsum("nc,nck->nk", weights[sel], self.texcoords[face[sel]])
                cut[sel] = ~self.masks[m].opaque(uv)
            hit[rays[valid & ~cut]] = True
            t = np.asarray(pi.t, np.float64)
            rays, t, face = rays[cut], t[cut], face[cut]
            if not len(rays):
                return hit, tests
            # on from just past the cut-out hit: rt_offset.glsl's offset along the face's
            # normal turned the way the ray goes (along the ray, a grazing ray met the same
            # face again and again)
            d = direction[rays]
            normal = self.normals[face]
            normal = np.where((np.sum(normal * d, axis=1) < 0)[:, None], -normal, normal)
            past = offset_ray(origin[rays] + (t[:, None] * d).astype(np.float32), normal)
            maxt[rays] -= np.linalg.norm(past.astype(np.float64) - origin[rays], axis=1)
            origin[rays] = past
        hit[rays] = ray_test(origin[rays], direction[rays], maxt[rays])
        return hit, tests
