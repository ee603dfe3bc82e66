"""Config's scene schema, above yaml_source, mesh_files, field_types and motion_schema: camera,
lights, shapes and the scene file, and load_scenes, which validates one."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal, Union, get_args

import numpy as np
from pydantic import BeforeValidator, Field, ValidationError, field_validator, model_validator

from .alpha_files import Alpha, read_alpha_texture, resolve_texture_path
from .field_types import Coordinate, FieldOfView, Size, Strict, Vec3, vector_norm
from .limits import DEFAULT_TRIANGLE_BUDGET, MAX_COORDINATE, MAX_DEPTH_RATIO
from .mesh_files import check_mesh, mesh_parts, resolve_mesh_path
from .motion_schema import Motion
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


class Array(Strict):
    """Copies of an object on a grid: ``count`` along x, y, z, ``step`` apart."""

    count: tuple[int, int, int] = (1, 1, 1)
    step: Vec3 = (0.0, 0.0, 0.0)

    @field_validator("count")
    @classmethod
    def _count(cls, v):
        if min(v) < 1 or math.prod(v) > 10000:
            raise ValueError(f"each count must be >= 1 and their product <= 10000, got {v}")
        return v


class Placed(Strict):
    """Where an object goes. Its vertices, in its own frame (a shape centred at its origin; a
    mesh file's own coordinates, never recentred, turned first so that the file's ``up`` is
    +z), are scaled (``scale``), then rotated about x, then y, then z (``rotate``, degrees),
    then moved (``translate``); ``array`` copies the result. ``shadowbench list --scene NAME``
    prints each object's bounds as placed."""

    name: str | None = Field(None, min_length=1)  # what an object motion may call it
    translate: Vec3 = (0.0, 0.0, 0.0)
    rotate: Vec3 = (0.0, 0.0, 0.0)  # degrees about x, then y, then z
    scale: Union[Size, tuple[Size, Size, Size]] = 1.0
    array: Array | None = None
    albedo: float = Field(0.8, ge=0, le=1)
    alpha: Alpha | None = None  # a cut-out (alpha_files.py); opaque without it

    @model_validator(mode="after")
    def _texture_coordinates(self):
        shape = getattr(self, "shape", None)
        if self.alpha is not None and shape not in SHAPES_WITH_TEXCOORDS:
            raise ValueError(f"alpha: a {shape} has no texture coordinates (trimesh makes none "
                             "for it); alpha cuts out a plane or a mesh file with texture "
                             "coordinates")
        return self

    def triangles(self) -> int:
        """Triangles of one copy (trimesh's construction of the shape; at most, for a lathe)."""
        raise NotImplementedError


# the shapes whose vertices carry texture coordinates: a plane's u, v over its size; a mesh
# file's own (checked when the file is loaded)
SHAPES_WITH_TEXCOORDS = ("plane", "mesh")


class Plane(Placed):
    shape: Literal["plane"]
    size: tuple[Size, Size] = (10.0, 10.0)

    def triangles(self) -> int:
        return 2


class Box(Placed):
    shape: Literal["box"]
    size: tuple[Size, Size, Size] = (1.0, 1.0, 1.0)

    def triangles(self) -> int:
        return 12


class Sphere(Placed):
    shape: Literal["sphere"]
    radius: Size = 1.0
    subdivisions: int = Field(3, ge=1, le=5)

    def triangles(self) -> int:
        return 20 * 4 ** self.subdivisions


class Cylinder(Placed):
    shape: Literal["cylinder"]
    radius: Size = 0.5
    height: Size = 1.0
    sections: int = Field(32, ge=3, le=256)

    def triangles(self) -> int:
        return 4 * self.sections


class Capsule(Placed):
    shape: Literal["capsule"]
    radius: Size = 0.25
    height: Size = 1.0  # between the centres of the two caps
    sections: int = Field(16, ge=3, le=128)

    def triangles(self) -> int:
        return 2 * (self.sections + self.sections % 2) ** 2  # trimesh rounds odd counts up


class Lathe(Placed):
    """A solid of revolution about +z from a profile of (radius, z) points, bottom to top."""

    shape: Literal["lathe"]
    profile: list[tuple[Annotated[float, Field(ge=0, le=MAX_COORDINATE)], Coordinate]]
    sections: int = Field(24, ge=3, le=256)

    @field_validator("profile")
    @classmethod
    def _profile(cls, v):
        if len(v) < 2:
            raise ValueError("needs at least two (radius, z) points")
        if not any(r > 0 for r, _ in v):
            raise ValueError("needs a radius > 0 (with every radius 0 it is a line, no surface)")
        return v

    def triangles(self) -> int:
        return 2 * self.sections * (len(self.profile) - 1)


class MeshFile(Placed):
    """A mesh file: ``path`` relative to the scene file, or with ``package:`` a file an
    installed package ships: relative to the folder of the top-level import package of that
    name (``{shape: mesh, package: pymeshlab, path: tests/sample_meshes/airplane.obj}``), else
    among the files the distribution of that name installed, its data files outside the
    import packages included (``{package: kivy-examples, path:
    share/kivy-examples/3Drendering/monkey.obj}``: :mod:`.mesh_packages`); nothing is
    imported."""

    shape: Literal["mesh"]
    path: str  # .obj, .ply, .stl, .off, .glb, .gltf or .dae
    up: Literal["y", "z"] = "z"  # the file's up axis; a y-up file is turned so +y is +z
    # an import package's name or a distribution's (PEP 508: letters, digits, . _ -)
    package: Annotated[str, Field(pattern=r"^[A-Za-z0-9]([A-Za-z0-9._-]*[A-Za-z0-9])?$")] | None = None

    @model_validator(mode="after")
    def _inside_the_package(self):
        if self.package is not None:
            p = Path(self.path)
            if p.is_absolute() or ".." in p.parts:
                raise ValueError(f"path {self.path!r}: with package: it must be relative to the "
                                 "package's folder (or its installed files), without '..'")
        return self

    @property
    def label(self) -> str:
        """How the file is named in the manifest and the rows: ``package:path`` or the path."""
        return f"{self.package}:{self.path}" if self.package else self.path


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


SceneObject = Annotated[
    Union[Plane, Box, Sphere, Cylinder, Capsule, Lathe, MeshFile], Field(discriminator="shape")
]


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
