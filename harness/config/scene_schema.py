"""Config's scene schema, above yaml_source, mesh_files, field_types, motion_schema and
object_schema (the shapes): camera, lights, families and the scene file, and load_scenes, which
validates one."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal, Union, get_args

import numpy as np
from pydantic import BeforeValidator, Field, ValidationError, field_validator, model_validator

from .alpha_files import read_alpha_texture, resolve_texture_path
from .field_types import FieldOfView, Size, Strict, Vec3, vector_norm
from .limits import DEFAULT_TRIANGLE_BUDGET, MAX_DEPTH_RATIO
from .mesh_files import check_mesh, mesh_parts, resolve_mesh_path
from .motion_schema import Motion
from .object_schema import MeshFile, Placed, SceneObject
from .yaml_source import check_name, key_error, read_yaml, validation_error

class Camera(Strict):
    position: Vec3
    target: Vec3
    up: Vec3 = (0.0, 0.0, 1.0)
    yfov: FieldOfView = 60.0
    near: Size = 0.1
    far: Size = 100.0

    @model_validator(mode="after")
    def _geometry(self):
        if self.far <= self.near:
            raise ValueError(f"far: must be greater than near ({self.near}), got {self.far}")
        if self.far / self.near > MAX_DEPTH_RATIO:
            raise ValueError(f"far: far / near is {self.far / self.near:.3g}; a 24-bit depth "
                             f"buffer resolves at most {MAX_DEPTH_RATIO} (2^20): raise near or "
                             "lower far")
        view = np.subtract(self.target, self.position)
        if vector_norm(view) == 0:
            raise ValueError("target: equals position")
        if vector_norm(self.up) == 0:
            raise ValueError("up: must not be the zero vector")
        if vector_norm(np.cross(view / vector_norm(view), np.asarray(self.up) / vector_norm(self.up))) < 1e-6:
            raise ValueError("up: is parallel to the view direction")
        return self


class DirectionalLight(Strict):
    type: Literal["directional"]
    direction: Vec3  # the direction light travels

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v):
        if vector_norm(v) == 0:
            raise ValueError("must not be the zero vector")
        return v


class SpotLight(Strict):
    type: Literal["spot"]
    position: Vec3
    target: Vec3
    fov: FieldOfView = 60.0  # full cone angle in degrees

    @model_validator(mode="after")
    def _aim(self):
        if vector_norm(np.subtract(self.target, self.position)) == 0:
            raise ValueError("target: equals position")
        return self


class PointLight(Strict):
    """An omnidirectional light at ``position``: no direction, cone or target."""

    type: Literal["point"]
    position: Vec3


Light = Annotated[Union[DirectionalLight, SpotLight, PointLight], Field(discriminator="type")]
LIGHT_TYPES = tuple(get_args(kind.model_fields["type"].annotation)[0]
                    for kind in (DirectionalLight, SpotLight, PointLight))


def _triangle_count(value):
    """A triangle count: an integer, or a number written like 1e5 (YAML reads 1e5 as text)."""
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            raise ValueError(f"must be a number of triangles such as 1e5, got {value!r}") from None
    if isinstance(value, float):
        if not value.is_integer():
            raise ValueError(f"must be a whole number of triangles, got {value}")
        value = int(value)
    return value


TriangleCount = Annotated[int, BeforeValidator(_triangle_count), Field(ge=1)]


class Family(Strict):
    """Procedural geometry of about ``triangles`` triangles (harness/scene/families.py): at most that
    many, and within 5% below. ``seed`` fixes its random layout. ``cutouts: false`` draws a
    family's alpha-tested parts (``cards``) opaque: the same triangles, for the comparison."""

    kind: Literal["tessellation", "instancing", "architecture", "foliage", "cards"]
    triangles: TriangleCount
    seed: int = Field(0, ge=0)
    cutouts: bool = True

    @model_validator(mode="after")
    def _enough(self):
        least = FAMILY_MIN_TRIANGLES[self.kind]
        if self.triangles < least:
            raise ValueError(f"triangles: the {self.kind} family needs at least {least:,} "
                             f"triangles to land within 5% of its target, got {self.triangles:,}")
        return self

    def at(self, triangles: int) -> "Family":
        """The family at another size; a ValueError naming why it cannot be."""
        try:
            return Family.model_validate({**self.model_dump(), "triangles": triangles})
        except ValidationError as e:
            raise ValueError(e.errors()[0]["msg"].removeprefix("Value error, ")
                             .removeprefix("triangles: ")) from None


# the smallest size each family reaches within 5%: one refined box and plane; otherwise a few
# object copies of up to 320 triangles each
FAMILY_MIN_TRIANGLES = {"tessellation": 100, "instancing": 1000, "architecture": 1000,
                        "foliage": 1000, "cards": 1000}


def check_resolution(size):
    """An image size (width, height), each in [16, 8192]."""
    if not all(16 <= x <= 8192 for x in size):
        raise ValueError(f"width and height must be in [16, 8192], got {list(size)}")
    return size


class Scene(Strict):
    description: str | None = None  # one sentence: what the scene is for (shown, never hashed)
    resolution: tuple[int, int] = (512, 512)
    camera: Camera
    light: Light
    effects: list[Literal["shadow", "direct"]] = ["shadow"]
    ambient: float = Field(0.1, ge=0, le=1)
    objects: list[SceneObject] = []
    family: Family | None = None  # procedural geometry besides the objects
    motion: Motion | None = None  # a still scene without it

    _res = field_validator("resolution")(lambda cls, v: check_resolution(v))

    @field_validator("effects")
    @classmethod
    def _effects(cls, v):
        if "shadow" not in v:
            raise ValueError("must include 'shadow'")
        return v

    @model_validator(mode="after")
    def _direct_without_cutouts(self):
        if "direct" in self.effects and self.family is not None and self.family.kind == "cards":
            raise ValueError(f"effects: {DIRECT_WITH_CUTOUTS.removeprefix('direct: ')}")
        return self

    @field_validator("objects")
    @classmethod
    def _objects(cls, v):
        named = {}
        for i, obj in enumerate(v):
            if obj.name in named:
                raise ValueError(f"{i}.name: {obj.name!r} names object {named[obj.name]} "
                                 "too; names are unique within a scene")
            if obj.name is not None:
                named[obj.name] = i
        return v

    @model_validator(mode="after")
    def _geometry(self):
        if not self.objects and self.family is None:
            raise ValueError("objects: must list at least one object (or the scene a family)")
        return self

    def at_triangles(self, triangles: int) -> "Scene":
        """The scene with its family at another size."""
        return self.model_copy(update={"family": self.family.at(triangles)})

    @model_validator(mode="after")
    def _moving_objects(self):
        moved = set()
        for i, path in enumerate(self.motion.objects if self.motion else ()):
            key = f"motion.objects.{i}.object"
            try:
                index = self.object_index(path.object)
            except KeyError as e:
                raise ValueError(f"{key}: {e.args[0]}") from None
            if index in moved:
                raise ValueError(f"{key}: object {index} moves along another path too")
            moved.add(index)
        return self

    def object_index(self, ref: int | str) -> int:
        """The index in ``objects`` of ``ref``, an index or an object's name."""
        if isinstance(ref, int):
            if ref >= len(self.objects):
                raise KeyError(f"no object {ref}: the scene has {len(self.objects)} "
                               f"(0 to {len(self.objects) - 1})")
            return ref
        for index, obj in enumerate(self.objects):
            if obj.name == ref:
                return index
        named = sorted(obj.name for obj in self.objects if obj.name is not None)
        raise KeyError(f"no object named {ref!r}; named: {', '.join(named) or 'none'}")


class SceneFile(Strict):
    scenes: dict[str, Scene]



def _within_budget(path: Path, node, loc: tuple, total: int, budget: int | None) -> None:
    if budget is not None and total > budget:
        raise key_error(path, node, loc, f"{total:,} triangles, more than the budget of "
                        f"{budget:,} (what fits 4 GiB for every technique; an experiment may "
                        "raise it with triangle_budget:)")


# Mitsuba's direct integrator tests its shadow rays with ray_test, every surface opaque
DIRECT_WITH_CUTOUTS = ("direct: the shaded reference cannot simulate alpha-tested casters "
                       "(its shadow rays see every surface opaque); use effects: [shadow]")


def _cut_out(path: Path, obj: Placed) -> bool:
    """Whether the object has a cut-out: its ``alpha`` key, or a mesh file's own."""
    return obj.alpha is not None or (isinstance(obj, MeshFile) and any(
        k >= 0 for k in mesh_parts(resolve_mesh_path(path, obj), obj.up).part_cutouts))


def _check_alpha(path: Path, node, scene_name: str, index: int, obj: Placed) -> None:
    """The object's alpha texture readable (alpha_files.py), and a mesh file with alpha
    carrying texture coordinates on every part; a ConfigError naming the key otherwise."""
    loc = ("scenes", scene_name, "objects", index, "alpha")
    if obj.alpha.texture is not None:
        texture = resolve_texture_path(path, obj.alpha.texture)
        try:
            read_alpha_texture(texture)
        except FileNotFoundError:
            raise key_error(path, node, loc + ("texture",), f"no such file: {texture}") \
                from None
        except (OSError, ValueError) as e:
            raise key_error(path, node, loc + ("texture",),
                            getattr(e, "strerror", None) or str(e)) from None
    if isinstance(obj, MeshFile):
        parts = mesh_parts(resolve_mesh_path(path, obj), obj.up)
        bare = [n for n, uv in zip(parts.names, parts.texcoords) if uv is None]
        if bare:
            raise key_error(path, node, loc, f"{obj.label} has no texture coordinates (part "
                            f"{bare[0]!r}), so nothing to cut out by")


def load_scenes(path: str | Path, *, triangle_budget: int | None = DEFAULT_TRIANGLE_BUDGET,
                only=None) -> dict[str, Scene]:
    """Load and validate a scene file; mesh paths are resolved against the file's folder.
    Each scene's triangles (all copies) must fit ``triangle_budget`` (None: no budget).
    ``only``: the names of the scenes whose mesh files are loaded and counted (None: every
    scene); the others are validated as written, so one bad mesh path blocks only its own
    scene (:func:`check_scenes` checks them later, when they are chosen)."""
    path = Path(path)
    data, node = read_yaml(path)
    if isinstance(data, dict) and isinstance(data.get("scenes"), dict):
        for name in data["scenes"]:
            try:
                check_name("scene", name)
            except ValueError as e:
                raise key_error(path, node, ("scenes", name), str(e)) from None
    try:
        scene_file = SceneFile.model_validate(data)
    except ValidationError as e:
        raise validation_error(path, e, node, model=SceneFile) from None
    check_scenes(path, scene_file.scenes, scene_file.scenes if only is None else only,
                 triangle_budget, node)
    return scene_file.scenes


def check_scenes(path: str | Path, scenes: dict[str, Scene], names,
                 triangle_budget: int | None = DEFAULT_TRIANGLE_BUDGET, node=None) -> None:
    """The scenes ``names`` of the file ``path`` (loaded as ``scenes``): each mesh file usable,
    and each scene's triangles, all copies, within ``triangle_budget``; a ConfigError naming
    the key otherwise."""
    path = Path(path)
    if node is None:
        node = read_yaml(path)[1]
    for name in names:
        scene = scenes[name]
        total = scene.family.triangles if scene.family else 0
        _within_budget(path, node, ("scenes", name, "family", "triangles"), total,
                       triangle_budget)
        for i, obj in enumerate(scene.objects):
            copies = math.prod(obj.array.count if obj.array else (1, 1, 1))
            one = (check_mesh(path, node, name, i, obj, triangle_budget and
                               triangle_budget // copies)
                   if isinstance(obj, MeshFile) else obj.triangles())
            total += one * copies
            if obj.alpha is not None:
                _check_alpha(path, node, name, i, obj)
            if "direct" in scene.effects and _cut_out(path, obj):
                raise key_error(path, node, ("scenes", name, "effects"), DIRECT_WITH_CUTOUTS)
        _within_budget(path, node, ("scenes", name, "objects"), total, triangle_budget)
