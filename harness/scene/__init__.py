"""One neutral triangle scene, built once, from which both the GL and the Mitsuba scene are made.

Both renderers receive the same float32 vertex arrays, so a technique differs from the
reference only in how it computes shadows. Shading is flat (face normals) in both.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .. import config as cfg
from . import families
from . import motion as motion_paths
from . import topology
from .alpha import QUAD_UV, AlphaMask, pattern_texture
from ..machine.interrupt import raise_if_interrupted

if TYPE_CHECKING:  # imported where a scene is built: half a second of every command's start
    import trimesh


@dataclass(frozen=True)
class MeshPart:
    """One object copy: merged vertices and faces (for adjacency), its albedo, and the index
    of its object in the scene's ``objects`` (what an object motion moves). An alpha-tested
    part has ``alpha`` and its texture coordinates per face corner (per corner, so merging
    vertices for adjacency never merges two sides of a texture seam)."""

    name: str
    vertices: np.ndarray  # (V, 3) float32
    faces: np.ndarray  # (F, 3) int32
    albedo: float
    object_index: int = 0
    texcoords: np.ndarray | None = None  # (F, 3, 2) float32, glTF's convention (alpha.py)
    alpha: AlphaMask | None = None


@dataclass(frozen=True)
class Light:
    """The light in world space. ``direction`` is the way light travels (unit): a directional
    light's, or a spot light's axis; None for a point light, which shines every way."""

    type: str  # directional, spot or point
    direction: np.ndarray | None
    position: np.ndarray | None = None  # spot and point
    fov_deg: float | None = None  # spot only: full cone angle
    aim_distance: float = 1.0  # spot: |target - position|; point: to the camera's target

    @property
    def positional(self) -> bool:
        """Whether light leaves one point (spot and point): rays, volumes and maps start
        there, and irradiance falls off with the squared distance."""
        return self.type != "directional"

    @property
    def power_scale(self) -> float:
        """A positional light's intensity is scaled by its aim distance squared, so the surface
        it aims at (a spot's target; what the camera looks at, for a point light) receives
        about the irradiance a directional light of the same power gives."""
        return self.aim_distance ** 2 if self.positional else 1.0

    def inside_cone(self, points: np.ndarray) -> np.ndarray:
        """Spot light: whether each point lies inside the cone (its full angle ``fov_deg``)."""
        d = np.asarray(points, dtype=np.float64) - self.position
        distance = np.maximum(np.linalg.norm(d, axis=-1), 1e-30)
        return (d @ self.direction) / distance >= np.cos(np.radians(self.fov_deg / 2))

    def to_light(self, points: np.ndarray) -> np.ndarray:
        """Unit vectors from surface points toward the light, shape like ``points``."""
        if self.type == "directional":
            return np.broadcast_to(-self.direction, points.shape).astype(np.float32)
        d = self.position - points
        return d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-30)


@dataclass(frozen=True)
class BuiltScene:
    name: str
    config: cfg.Scene
    parts: list[MeshPart]
    light: Light
    key: str  # content hash of the scene description (mesh file contents included)
    source: Path | None = field(default=None, compare=False)
    # a frame of a moving scene whose objects moved: each part's rigid transform (P, 4, 4) from
    # the moving scene's parts as written (None: none moved)
    poses: np.ndarray | None = field(default=None, compare=False)

    @property
    def width(self) -> int:
        return self.config.resolution[0]

    @property
    def height(self) -> int:
        return self.config.resolution[1]

    @cached_property
    def triangles(self) -> np.ndarray:
        """All triangles, unrolled: (T, 3, 3) float32."""
        return np.concatenate([p.vertices[p.faces] for p in self.parts]).astype(np.float32)

    @cached_property
    def indexed(self) -> tuple[np.ndarray, np.ndarray]:
        """All parts as one indexed mesh: shared vertices (V, 3) float32 and faces (T, 3)
        uint32 into them, face i being triangle i of :attr:`triangles`."""
        offsets = np.cumsum([0] + [len(p.vertices) for p in self.parts])
        vertices = np.concatenate([p.vertices for p in self.parts]).astype(np.float32)
        faces = np.concatenate([p.faces + o for p, o in zip(self.parts, offsets)])
        return vertices, faces.astype(np.uint32)

    @cached_property
    def face_normals(self) -> np.ndarray:
        tri = self.triangles.astype(np.float64)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return (n / np.where(length > 0, length, 1)).astype(np.float32)

    @cached_property
    def face_albedo(self) -> np.ndarray:
        return np.concatenate(
            [np.full(len(p.faces), p.albedo, np.float32) for p in self.parts]
        )

    @cached_property
    def alpha_masks(self) -> tuple[AlphaMask, ...]:
        """The distinct cut-outs of the scene's parts, in part order (one object's copies
        share theirs)."""
        masks = {id(p.alpha): p.alpha for p in self.parts if p.alpha is not None}
        return tuple(masks.values())

    @property
    def has_alpha(self) -> bool:
        """Whether any caster is alpha-tested."""
        return bool(self.alpha_masks)

    @cached_property
    def face_mask(self) -> np.ndarray:
        """Per triangle of :attr:`triangles`, its cut-out's index in :attr:`alpha_masks`, or
        -1 where it is opaque: (T,) int32."""
        index = {id(m): i for i, m in enumerate(self.alpha_masks)}
        return np.concatenate([np.full(len(p.faces), index.get(id(p.alpha), -1), np.int32)
                               for p in self.parts])

    @cached_property
    def face_texcoords(self) -> np.ndarray:
        """Per triangle of :attr:`triangles`, its corners' texture coordinates (T, 3, 2)
        float32; zeros on opaque parts."""
        return np.concatenate([
            p.texcoords.astype(np.float32) if p.alpha is not None
            else np.zeros((len(p.faces), 3, 2), np.float32) for p in self.parts])

    @cached_property
    def bounds(self) -> np.ndarray:
        """Axis-aligned bounds of all geometry, (2, 3) float64: min row, max row."""
        v = self.triangles.reshape(-1, 3)
        return np.stack([v.min(0), v.max(0)]).astype(np.float64)

    @cached_property
    def edges(self) -> topology.Edges:
        return topology.edges([p.vertices for p in self.parts], [p.faces for p in self.parts])

    @property
    def counts(self) -> dict[str, int]:
        """The per-run counts: triangles, parts, open parts, and the shadow edges seen from
        this scene's light (harness.scene.topology)."""
        return {"triangles": len(self.triangles), "parts": self.edges.parts,
                "open_parts": self.edges.open_parts,
                "shadow_edges": topology.shadow_edges(self.edges, self.triangles, self.light)}

    @property
    def mesh_notes(self) -> str:
        """What the scene's mesh files hold that defines no triangle, one line per file that
        has any: ``models/temple.obj: skipped 201 faces with fewer than 3 vertices``."""
        notes = []
        for obj in self.config.objects:
            if isinstance(obj, cfg.MeshFile):
                path = cfg.resolve_mesh_path(self.source or Path("."), obj)
                if note := cfg.mesh_parts(path, obj.up).notes():
                    notes.append(f"{obj.label}: {note}")
        return "\n".join(notes)

    def _sharing_geometry(self, scene: "BuiltScene") -> "BuiltScene":
        """``scene`` (of the same triangles) given what this one computed of them."""
        for name in _GEOMETRY:
            if name in self.__dict__:
                scene.__dict__[name] = self.__dict__[name]
        return scene

    def with_resolution(self, width: int, height: int) -> "BuiltScene":
        new_config = self.config.model_copy(update={"resolution": (width, height)})
        return self._sharing_geometry(BuiltScene(
            self.name, new_config, self.parts, self.light,
            scene_key(new_config, self.source, self.poses), self.source, self.poses))

    def orbited(self, degrees: float, name: str) -> "BuiltScene":
        """This still scene seen from a camera orbited ``degrees`` about its up axis through its
        target (as a moving scene's ``camera_orbit`` turns it), named ``name``: the same
        triangles and light from another view (tune's held-out view)."""
        camera = self.config.camera
        turn = motion_paths.rotation(camera.up, degrees)
        target = np.asarray(camera.target, dtype=np.float64)
        position = turn @ (np.asarray(camera.position, dtype=np.float64) - target) + target
        config = self.config.model_copy(update={"camera": camera.model_copy(
            update={"position": tuple(float(x) for x in position)})})
        return self._sharing_geometry(BuiltScene(
            name, config, self.parts, self.light, scene_key(config, self.source, self.poses),
            self.source, self.poses))

    @property
    def frames(self) -> int:
        """Frames of its ``motion`` sequence; 1 for a still scene."""
        return self.config.motion.frames if self.config.motion else 1

    def at_frame(self, t: int) -> "BuiltScene":
        """Frame ``t`` of a moving scene: a still scene with that frame's camera and light and
        its objects where their paths put them (harness/scene/motion.py). Its key is that still
        scene's (with the parts' poses where objects moved), so each frame has its own
        reference cache entry and frame 0 shares the scene's without motion. A still scene's
        only frame is itself."""
        if self.config.motion is None:
            if t != 0:
                raise IndexError(f"frame {t} of the still scene {self.name!r}")
            return self
        centre = self.bounds.mean(axis=0)
        config = motion_paths.scene_at(self.config, centre, t)
        poses = motion_paths.object_poses(self.config, self.parts, centre, t)
        parts = self.parts if poses is None else motion_paths.posed(self.parts, poses)
        frame = BuiltScene(self.name, config, parts, _light(config),
                           scene_key(config, self.source, poses), self.source, poses)
        # the same triangles, unless objects moved: computed once per sequence
        return frame if poses is not None else self._sharing_geometry(frame)


# BuiltScene's cached properties that depend only on the geometry
_GEOMETRY = ("triangles", "indexed", "face_normals", "face_albedo", "bounds", "edges",
             "alpha_masks", "face_mask", "face_texcoords")


def _transform(obj: cfg.Placed) -> np.ndarray:
    import trimesh

    scale = np.broadcast_to(np.asarray(obj.scale, dtype=float), (3,))
    rx, ry, rz = np.radians(obj.rotate)
    rotation = (
        trimesh.transformations.rotation_matrix(rz, [0, 0, 1])
        @ trimesh.transformations.rotation_matrix(ry, [0, 1, 0])
        @ trimesh.transformations.rotation_matrix(rx, [1, 0, 0])
    )
    m = trimesh.transformations.translation_matrix(obj.translate) @ rotation
    return m @ np.diag([*scale, 1.0])


def _plane(size) -> trimesh.Trimesh:
    import trimesh

    sx, sy = size[0] / 2, size[1] / 2
    v = [[-sx, -sy, 0], [sx, -sy, 0], [sx, sy, 0], [-sx, sy, 0]]
    return trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)


def _base_mesh(obj) -> trimesh.Trimesh:
    import trimesh.creation as c

    match obj:
        case cfg.Plane():
            return _plane(obj.size)
        case cfg.Box():
            return c.box(extents=obj.size)
        case cfg.Sphere():
            return c.icosphere(subdivisions=obj.subdivisions, radius=obj.radius)
        case cfg.Cylinder():
            return c.cylinder(radius=obj.radius, height=obj.height, sections=obj.sections)
        case cfg.Capsule():
            return c.capsule(height=obj.height, radius=obj.radius,
                             count=[obj.sections, obj.sections])
        case cfg.Lathe():
            return c.revolve(np.asarray(obj.profile, dtype=float), sections=obj.sections)
    raise TypeError(f"unknown object {obj!r}")


def _object_parts(obj, source: Path | None
                  ) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None,
                                  AlphaMask | None]]:
    """(name, vertices float64, faces int32, corners' texture coordinates or None, the file's
    own cut-out or None) of one copy of the object, in its own frame: a mesh file's parts
    (cached: harness.config.mesh_files), or trimesh's construction (a plane's texture
    coordinates: alpha.QUAD_UV, its corners being a quad's)."""
    if isinstance(obj, cfg.MeshFile):
        mesh = cfg.mesh_parts(cfg.resolve_mesh_path(source or Path("."), obj), obj.up)
        own = [AlphaMask(texture, cutoff, f"{obj.label}: {name}")
               for texture, cutoff, name in mesh.cutouts]
        return [(f":{name}" if len(mesh.names) > 1 else "", v, f, uv,
                 own[k] if k >= 0 else None)
                for name, v, f, uv, k in zip(mesh.names, mesh.vertices, mesh.faces,
                                             mesh.texcoords, mesh.part_cutouts)]
    base = _base_mesh(obj)
    faces = np.asarray(base.faces, dtype=np.int32)
    return [("", np.asarray(base.vertices, dtype=np.float64), faces,
             QUAD_UV[faces] if isinstance(obj, cfg.Plane) else None, None)]


def _alpha_mask(obj, source: Path | None) -> AlphaMask | None:
    """The object's cut-out as its ``alpha`` key says (checked at load: cfg.check_scenes)."""
    alpha = obj.alpha
    if alpha is None:
        return None
    if alpha.texture is not None:
        path = cfg.resolve_texture_path(source or Path("."), alpha.texture)
        return AlphaMask(cfg.read_alpha_texture(path), alpha.cutoff, str(path))
    width, height = alpha.size
    return AlphaMask(pattern_texture(alpha.pattern, width, height), alpha.cutoff,
                     f"pattern {alpha.pattern} {width}x{height}")


FAMILY_ALBEDO = 0.8  # the objects' default


def build_parts(scene: cfg.Scene, source: Path | None = None) -> list[MeshPart]:
    import trimesh

    parts = []
    for index, obj in enumerate(scene.objects):
        raise_if_interrupted()  # trimesh catches BaseException, Ctrl-C included
        pieces = _object_parts(obj, source)
        raise_if_interrupted()
        transform = _transform(obj)
        array = obj.array or cfg.Array()
        mask = _alpha_mask(obj, source)  # the object's alpha key: every part's cut-out
        for suffix, local, faces, texcoords, own in pieces:
            vertices = trimesh.transformations.transform_points(local, transform)
            for ix in np.ndindex(*array.count):
                offset = np.asarray(ix, dtype=float) * np.asarray(array.step)
                parts.append(MeshPart(
                    name=f"{index}:{obj.shape}{suffix}" + (f"{list(ix)}" if obj.array else ""),
                    vertices=(vertices + offset).astype(np.float32),
                    faces=faces,
                    albedo=obj.albedo,
                    object_index=index,
                    texcoords=texcoords if (mask or own) is not None else None,
                    alpha=mask or own,
                ))
    if scene.family is not None:  # no object of its own: object motions never move it
        mask = families.alpha_mask(scene.family.kind)
        parts += [MeshPart(f"{scene.family.kind}:{name}", vertices, faces, FAMILY_ALBEDO, -1,
                           texcoords, None if texcoords is None else mask)
                  for name, vertices, faces, texcoords in families.build(scene.family)]
    return parts


def _light(scene: cfg.Scene) -> Light:
    light = scene.light
    if isinstance(light, cfg.DirectionalLight):
        d = np.asarray(light.direction, dtype=np.float64)
        return Light("directional", d / np.linalg.norm(d))
    pos = np.asarray(light.position, dtype=np.float64)
    if isinstance(light, cfg.PointLight):
        # a point light inside what the camera looks at keeps its intensity as written
        aim = float(np.linalg.norm(np.asarray(scene.camera.target, dtype=np.float64) - pos))
        return Light("point", None, pos, aim_distance=aim or 1.0)
    d = np.asarray(light.target, dtype=np.float64) - pos
    distance = float(np.linalg.norm(d))
    return Light("spot", d / distance, pos, light.fov, distance)


def scene_key(scene: cfg.Scene, source: Path | None = None,
              poses: np.ndarray | None = None) -> str:
    """Hash of the scene's geometry, light, camera and motion, including the bytes of any mesh
    files it loads, and of ``poses`` (a frame whose objects moved: BuiltScene.poses); its
    ``description`` and the objects' names are labels and stay out, so rewording them keeps
    references and run ids. A still scene hashes as it did before scenes could move (no
    ``motion`` key), a moving one as before objects could (no ``motion.objects`` when none
    move), a scene without a family as before families (no ``family`` key), a family with its
    cut-outs as before they could be turned off (no ``cutouts`` key), an object without
    a cut-out as before objects could have one (no ``alpha`` key); an alpha texture's bytes
    are hashed like a mesh file's."""
    # an object without alpha hashes as before objects could have one
    labels = {"description": True, "objects": {
        i: {"name"} if obj.alpha is not None else {"name", "alpha"}
        for i, obj in enumerate(scene.objects)}}
    if scene.motion is None:
        labels["motion"] = True
    elif not scene.motion.objects:
        labels["motion"] = {"objects"}
    if scene.family is None:
        labels["family"] = True
    elif scene.family.cutouts:  # a family with its cut-outs hashes as before they could go
        labels["family"] = {"cutouts"}
    geometry = scene.model_dump(mode="json", exclude=labels)
    h = hashlib.sha256(json.dumps(geometry, sort_keys=True).encode())
    for obj in scene.objects:
        if isinstance(obj, cfg.MeshFile):
            h.update(cfg.resolve_mesh_path(source or Path("."), obj).read_bytes())
        if obj.alpha is not None and obj.alpha.texture is not None:
            h.update(cfg.resolve_texture_path(source or Path("."), obj.alpha.texture)
                     .read_bytes())
    if poses is not None:
        h.update(np.ascontiguousarray(poses, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


def build_scene(name: str, scene: cfg.Scene, source: Path | None = None) -> BuiltScene:
    return BuiltScene(name, scene, build_parts(scene, source), _light(scene),
                      scene_key(scene, source), source)


def load_scene(name: str, scene_file: str | Path = "scenes.yaml") -> BuiltScene:
    """The scene ``name`` of ``scene_file``; ``family@size`` (``architecture@1e6``) is a family
    scene at another size, as an experiment's ``triangles`` makes it (the same key)."""
    base, at, size = name.partition("@")
    scenes = cfg.load_scenes(scene_file, only=())  # the meshes of this scene alone, below
    if base not in scenes:
        raise cfg.ConfigError(
            f"{scene_file}: no scene named {base!r}; it has {', '.join(sorted(scenes))}"
        )
    cfg.check_scenes(scene_file, scenes, [base])
    scene = scenes[base]
    if at:
        if scene.family is None:
            raise cfg.ConfigError(f"{scene_file}: scene {base!r} has no family, so no "
                                  f"{name!r}: only family scenes take a size")
        try:
            triangles = int(float(size))
            if triangles != float(size) or triangles < 1:
                raise ValueError
        except ValueError:
            raise cfg.ConfigError(f"{name!r}: the size after @ must be a whole number of "
                                  f"triangles such as 1e5, got {size!r}") from None
        if triangles > cfg.DEFAULT_TRIANGLE_BUDGET:
            raise cfg.ConfigError(f"{name!r}: {triangles:,} triangles, more than the budget of "
                                  f"{cfg.DEFAULT_TRIANGLE_BUDGET:,}")
        try:
            scene = scene.at_triangles(triangles)
        except ValueError as e:
            raise cfg.ConfigError(f"{name!r}: {e}") from None
    return build_scene(name, scene, Path(scene_file))
