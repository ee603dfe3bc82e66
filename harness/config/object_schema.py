"""Config's objects of a scene, above alpha_files, field_types and limits: where an object goes
(:class:`Placed`, an :class:`Array` of copies) and each shape, the mesh file among them; a
scene's ``objects`` list is :data:`SceneObject`."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Literal, Union

from pydantic import Field, field_validator, model_validator

from .alpha_files import Alpha
from .field_types import Coordinate, Size, Strict, Vec3
from .limits import MAX_COORDINATE


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


SceneObject = Annotated[
    Union[Plane, Box, Sphere, Cylinder, Capsule, Lathe, MeshFile], Field(discriminator="shape")
]
