"""The scene file and experiment schema, validated at load.

Every problem is a :class:`ConfigError` whose one-line message names the file, the key path
and (where the YAML has it) the line, e.g.
``scenes.yaml:12: scenes.box_plane.camera.yfov: must be in [0.01, 180), got 190``.
Unknown keys are errors, never silently ignored; so are a key given twice in one mapping
(both lines named) and an alias that refers to itself.

Every number must be finite, and within what the renderers can represent:

- coordinates, sizes and distances at most ``MAX_COORDINATE`` (1e7) in magnitude: vertices are
  float32, whose step is already one unit at 1e7;
- sizes, radii, heights and scales > 0 (a zero scale flattens an object to nothing);
- ``camera.far / camera.near`` at most ``MAX_DEPTH_RATIO`` (2^20): the camera pass writes a
  24-bit depth buffer cleared to 1 and keeps fragments with depth < 1. A point at distance d
  lies ``near (far - d) / ((far - near) d)`` below 1 in window depth, so with far/near = R every
  point nearer than far/2 is at least 2^24 / R steps in front of the cleared depth: 16 at the
  limit. At near 1e-7, far 1e9 a box 6 units away rounds to 1 and the GL view covers nothing;
- a scene's triangles at most ``DEFAULT_TRIANGLE_BUDGET`` (1,000,000: about 0.8 GB and a minute
  per shadow-volume run on 2 cores), or the experiment's ``triangle_budget``;
- scene names (they name folders under ``--out``) from ``NAME_PATTERN``: letters, digits,
  ``_``, ``-`` and ``.``, not starting with ``.``, at most 64 characters.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Literal, Union

import numpy as np
import yaml
from pydantic import (AfterValidator, BaseModel, ConfigDict, Field, ValidationError,
                      field_validator, model_validator)

from .timing import STATISTICS

MAX_COORDINATE = 1e7
MAX_DEPTH_RATIO = 2 ** 20
DEFAULT_TRIANGLE_BUDGET = 1_000_000
# degrees; no one benchmarks a narrower view, and toward 0 the projection's 1 / tan(fov / 2)
# overflows float32
MIN_FOV = 0.01
MAX_YAML_NODES = 1_000_000  # after aliases are expanded: a few alias levels can mean billions
NAME_PATTERN = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,63}")

Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
Size = Annotated[float, Field(gt=0, le=MAX_COORDINATE)]
Vec3 = tuple[Coordinate, Coordinate, Coordinate]


def _field_of_view(value: float) -> float:
    if not MIN_FOV <= value < 180:
        raise ValueError(f"must be in [{MIN_FOV}, 180), got {value}")
    return value


FieldOfView = Annotated[float, AfterValidator(_field_of_view)]


def square_number(value: int) -> int:
    """Validate a square sample count (a sqrt(n) x sqrt(n) grid)."""
    if value < 1 or math.isqrt(value) ** 2 != value:
        raise ValueError(f"must be a square number (1, 4, 9, 16, 25, ...), got {value}")
    return value


SquareInt = Annotated[int, AfterValidator(square_number)]


class ConfigError(Exception):
    """Bad input: the message is one line naming file, key path and, where known, line."""


def check_name(kind: str, name: str) -> str:
    """A scene or technique name becomes a folder and file name under ``--out``: only
    ``NAME_PATTERN`` names, so none can climb out of it, hide, or carry markup."""
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise ValueError(f"{kind} name {name!r}: use letters, digits, '_', '-' and '.' (not "
                         "first), at most 64 characters")
    return name


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def _norm(v) -> float:
    return float(np.linalg.norm(np.asarray(v, dtype=float)))


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
        if _norm(view) == 0:
            raise ValueError("target: equals position")
        if _norm(self.up) == 0:
            raise ValueError("up: must not be the zero vector")
        if _norm(np.cross(view / _norm(view), np.asarray(self.up) / _norm(self.up))) < 1e-6:
            raise ValueError("up: is parallel to the view direction")
        return self


class DirectionalLight(Strict):
    type: Literal["directional"]
    direction: Vec3  # the direction light travels

    @field_validator("direction")
    @classmethod
    def _nonzero(cls, v):
        if _norm(v) == 0:
            raise ValueError("must not be the zero vector")
        return v


class SpotLight(Strict):
    type: Literal["spot"]
    position: Vec3
    target: Vec3
    fov: FieldOfView = 60.0  # full cone angle in degrees

    @model_validator(mode="after")
    def _aim(self):
        if _norm(np.subtract(self.target, self.position)) == 0:
            raise ValueError("target: equals position")
        return self


Light = Annotated[Union[DirectionalLight, SpotLight], Field(discriminator="type")]


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
    translate: Vec3 = (0.0, 0.0, 0.0)
    rotate: Vec3 = (0.0, 0.0, 0.0)  # degrees about x, then y, then z
    scale: Union[Size, tuple[Size, Size, Size]] = 1.0
    array: Array | None = None
    albedo: float = Field(0.8, ge=0, le=1)

    def triangles(self) -> int:
        """Triangles of one copy (trimesh's construction of the shape; at most, for a lathe)."""
        raise NotImplementedError


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
    shape: Literal["mesh"]
    path: str


SceneObject = Annotated[
    Union[Plane, Box, Sphere, Cylinder, Capsule, Lathe, MeshFile], Field(discriminator="shape")
]


def check_resolution(size):
    """An image size (width, height), each in [16, 8192]."""
    if not all(16 <= x <= 8192 for x in size):
        raise ValueError(f"width and height must be in [16, 8192], got {list(size)}")
    return size


MAX_ORBIT_DEG = 3600.0  # ten turns: more is a typo, not a path
MIN_DOLLY = -10.0  # backing away to eleven times the starting distance


class Motion(Strict):
    """A moving scene: over ``frames`` frames the camera orbits its target about its up axis
    by ``camera_orbit`` degrees in total, the light (a directional light's direction; a spot
    light's position and target together) turns about the up axis through the centre of the
    scene's bounds by ``light_orbit`` degrees, and the camera moves toward its target by the
    fraction ``camera_dolly`` of its distance (negative: away). Frame t is at t / (frames - 1)
    of each path, so the first frame is the scene as written and the last ends the paths
    (harness/motion.py)."""

    frames: int = Field(ge=2, le=1000)
    camera_orbit: float = Field(0.0, ge=-MAX_ORBIT_DEG, le=MAX_ORBIT_DEG)
    light_orbit: float = Field(0.0, ge=-MAX_ORBIT_DEG, le=MAX_ORBIT_DEG)
    camera_dolly: float = Field(0.0, ge=MIN_DOLLY)

    @field_validator("camera_dolly")
    @classmethod
    def _short_of_the_target(cls, v):
        if v >= 1:
            raise ValueError(f"must be < 1: a dolly of 1 or more reaches or passes through the "
                             f"camera's target, got {v}")
        return v


class Scene(Strict):
    description: str | None = None  # one sentence: what the scene is for (shown, never hashed)
    resolution: tuple[int, int] = (512, 512)
    camera: Camera
    light: Light
    effects: list[Literal["shadow", "direct"]] = ["shadow"]
    ambient: float = Field(0.1, ge=0, le=1)
    objects: list[SceneObject]
    motion: Motion | None = None  # a still scene without it

    _res = field_validator("resolution")(lambda cls, v: check_resolution(v))

    @field_validator("effects")
    @classmethod
    def _effects(cls, v):
        if "shadow" not in v:
            raise ValueError("must include 'shadow'")
        return v

    @field_validator("objects")
    @classmethod
    def _objects(cls, v):
        if not v:
            raise ValueError("must list at least one object")
        return v


class SceneFile(Strict):
    scenes: dict[str, Scene]


def _line_of(node, path: tuple) -> int | None:
    """Line (1-based) of the deepest YAML node reachable along a pydantic error location."""
    line = None
    for key in path:
        if node is None:
            break
        line = node.start_mark.line + 1
        if isinstance(node, yaml.MappingNode):
            node = next((v for k, v in node.value if k.value == str(key)), None)
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
        elif isinstance(node, yaml.SequenceNode):
            continue  # a discriminator tag in the location, not a YAML key
        else:
            node = None
    if node is not None:
        line = node.start_mark.line + 1
    return line


def _clean_loc(loc: tuple, node) -> tuple:
    """The key path of a pydantic error location in the YAML document. Parts that are not keys
    or indices of the document (pydantic's union and discriminator tags such as 'box',
    'function-after[...]', 'bool') are dropped; a missing key at the end is kept."""
    out = []
    for i, part in enumerate(loc):
        last = i == len(loc) - 1
        if isinstance(node, yaml.MappingNode):
            child = next((v for k, v in node.value if k.value == str(part)), None)
            if child is not None or (last and "[" not in str(part)):
                out.append(part)
                node = child
        elif isinstance(node, yaml.SequenceNode) and isinstance(part, int):
            out.append(part)
            node = node.value[part] if part < len(node.value) else None
        elif node is None and "[" not in str(part):
            out.append(part)
    return tuple(out)


def format_validation_error(path: Path, err: ValidationError, root_node, prefix=()) -> str:
    first = err.errors()[0]
    loc = _clean_loc(prefix + tuple(first["loc"]), root_node)
    msg = first["msg"].removeprefix("Value error, ")
    if first["type"] == "extra_forbidden":
        msg = "unknown key"
    elif first["type"] == "missing":
        msg = "required key is missing"
    field, sep, rest = msg.partition(": ")
    if sep and field.isidentifier():  # a model-level check naming its field
        loc, msg = loc + (field,), rest
    keypath = ".".join(str(p) for p in loc)
    line = _line_of(root_node, loc)
    where = f"{path}:{line}" if line else str(path)
    more = len(err.errors()) - 1
    return f"{where}: {keypath}: {msg}" + (f" (and {more} more)" if more else "")


def read_yaml(path: Path):
    """Parse a YAML file; return (data, root node). Errors are ConfigErrors: a file that is not
    UTF-8 text, not YAML, repeats a key in one mapping, or expands past ``MAX_YAML_NODES``."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(f"{path}: not a text file (byte {e.object[e.start]:#04x} at offset "
                          f"{e.start} is not UTF-8)") from None
    except OSError as e:
        raise ConfigError(f"{path}: cannot read: {e.strerror}") from None
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        _check_nodes(path, node)
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = f":{mark.line + 1}" if mark else ""
        problem = " ".join(str(getattr(e, "problem", None) or e).split())
        raise ConfigError(f"{path}{line}: not valid YAML: {problem}") from None
    except RecursionError:
        raise ConfigError(f"{path}: not valid YAML: nested too deeply") from None
    return data, node


def _check_nodes(path: Path, root) -> None:
    """Duplicate keys (YAML loaders keep the last silently), aliases that contain themselves,
    and alias expansion past ``MAX_YAML_NODES`` (a few nested aliases can stand for billions of
    nodes) are errors. Merge keys (``<<: *anchor``) may be overridden: that is their purpose."""
    sizes: dict[int, int] = {}
    open_nodes: set[int] = set()

    def expanded(node) -> int:
        if id(node) in sizes:
            return sizes[id(node)]
        if id(node) in open_nodes:
            raise ConfigError(f"{path}:{node.start_mark.line + 1}: an alias refers to the node "
                              "that contains it")
        open_nodes.add(id(node))
        total = 1
        if isinstance(node, yaml.MappingNode):
            first_line: dict[tuple, int] = {}
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode) and key.tag != "tag:yaml.org,2002:merge":
                    line = key.start_mark.line + 1
                    if (key.tag, key.value) in first_line:
                        raise ConfigError(f"{path}:{line}: key {key.value!r} is given twice "
                                          f"in one mapping, at lines "
                                          f"{first_line[key.tag, key.value]} and {line}")
                    first_line[key.tag, key.value] = line
                total += expanded(key) + expanded(value)
        elif isinstance(node, yaml.SequenceNode):
            total += sum(expanded(child) for child in node.value)
        open_nodes.discard(id(node))
        sizes[id(node)] = total
        if total > MAX_YAML_NODES:
            raise ConfigError(f"{path}: its aliases expand to more than {MAX_YAML_NODES:,} "
                              "values")
        return total

    if root is not None:
        expanded(root)


def load_scenes(path: str | Path, *,
                triangle_budget: int | None = DEFAULT_TRIANGLE_BUDGET) -> dict[str, Scene]:
    """Load and validate a scene file; mesh paths are resolved against the file's folder.
    Each scene's triangles (all copies) must fit ``triangle_budget`` (None: no budget)."""
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
        raise ConfigError(format_validation_error(path, e, node)) from None
    for name, scene in scene_file.scenes.items():
        total = 0
        for i, obj in enumerate(scene.objects):
            one = (_check_mesh(path, node, name, i, obj) if isinstance(obj, MeshFile)
                   else obj.triangles())
            total += one * math.prod(obj.array.count if obj.array else (1, 1, 1))
        if triangle_budget is not None and total > triangle_budget:
            raise key_error(path, node, ("scenes", name, "objects"),
                            f"{total:,} triangles, more than the budget of {triangle_budget:,} "
                            "(an experiment may raise it with triangle_budget:)")
    return scene_file.scenes


def resolve_mesh_path(scene_path: Path, obj: MeshFile) -> Path:
    p = Path(obj.path)
    return p if p.is_absolute() else Path(scene_path).parent / p


def load_mesh(mesh_path: Path):
    """trimesh's mesh from a file; a ``ValueError`` naming what is wrong when it is not one."""
    import trimesh

    from .interrupt import raise_if_interrupted

    try:
        mesh = trimesh.load(mesh_path, force="mesh")
    except ModuleNotFoundError:
        # trimesh's last resort for text it cannot decode as UTF-8 is an optional module
        raise ValueError("not a mesh file trimesh can read (neither its binary format nor "
                         "UTF-8 text)") from None
    except Exception as e:  # trimesh raises many kinds for a bad file
        raise ValueError(" ".join(f"{type(e).__name__}: {e}".split())[:300]) from None
    finally:
        raise_if_interrupted()  # trimesh catches BaseException in places, Ctrl-C included
    faces = getattr(mesh, "faces", None)
    if faces is None or len(faces) == 0:
        raise ValueError("no triangles")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.all(np.abs(vertices) <= MAX_COORDINATE):
        raise ValueError(f"vertex coordinates must be finite and within +-{MAX_COORDINATE:g}")
    return mesh


def _check_mesh(path: Path, node, scene_name: str, index: int, obj: MeshFile) -> int:
    """The mesh file's triangle count; a ConfigError naming the key when it cannot be used."""
    loc = ("scenes", scene_name, "objects", index, "path")
    mesh_path = resolve_mesh_path(path, obj)
    if mesh_path.is_dir():
        raise key_error(path, node, loc, f"{mesh_path} is a folder, not a mesh file")
    if not mesh_path.is_file():
        raise key_error(path, node, loc, f"no such file: {mesh_path}")
    try:
        return len(load_mesh(mesh_path).faces)
    except ValueError as e:
        raise key_error(path, node, loc, f"cannot load mesh {mesh_path}: {e}") from None


# --- experiments -----------------------------------------------------------------------------

Scalar = Union[bool, int, float, str]


class Grid(Strict):
    """One parameter grid: every combination of ``product`` times each row of ``zip``,
    with ``set`` fixed; or, with ``curve``, the technique's quality curve from ``set`` (true:
    every declared knob and value; a mapping: those knobs, with these values), expanded by the
    planner, which knows the techniques' declarations."""

    # a non-finite value is the technique's error (runner.validate_params), named there
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=True)

    product: dict[str, list[Scalar]] = {}
    zip: dict[str, list[Scalar]] = {}
    set: dict[str, Scalar] = {}
    curve: Union[Literal[True], dict[str, list[Scalar]], None] = None

    @model_validator(mode="after")
    def _nonempty(self):
        if self.curve is not None and (self.product or self.zip):
            raise ValueError("curve: goes with set only, not with product or zip (a curve walks "
                             "one knob at a time)")
        if isinstance(self.curve, dict):
            if not self.curve:
                raise ValueError("curve: is empty; name a quality knob with its values, or "
                                 "write true for every declared one")
            for key, values in self.curve.items():
                if not values:
                    raise ValueError(f"curve.{key} is an empty list")
        kinds = {"product": self.product, "zip": self.zip, "set": self.set}
        for name in set().union(*kinds.values()):
            where = [k for k, values in kinds.items() if name in values]
            if len(where) > 1:
                raise ValueError(f"parameter {name!r} is in both {' and '.join(where)}; "
                                 "give each parameter in one of product, zip, set")
        for kind in ("product", "zip"):
            for key, values in getattr(self, kind).items():
                if not values:
                    raise ValueError(f"{kind}.{key} is an empty list")
        lengths = {len(v) for v in self.zip.values()}
        if len(lengths) > 1:
            raise ValueError(f"zip lists must have equal lengths, got {sorted(lengths)}")
        return self

    def combinations(self) -> list[dict]:
        import itertools

        names = list(self.product)
        prods = [dict(zip(names, values))
                 for values in itertools.product(*(self.product[n] for n in names))]
        rows = ([dict(zip(self.zip, values)) for values in zip(*self.zip.values())]
                if self.zip else [{}])
        return [{**self.set, **p, **z} for p in prods for z in rows]


class ReferenceSettings(Strict):
    samples: SquareInt = Field(16, le=1024)
    seed: int = Field(0, ge=0)


class Experiment(Strict):
    scene_file: str | None = None  # relative to the experiment file; default: --scene-file
    scenes: Union[Literal["all"], list[str]] = "all"
    # technique name -> grid(s); or "all": every registered technique at its defaults; or
    # "curves": every registered technique along its declared quality curve
    techniques: Union[Literal["all", "curves"], dict[str, Union[Grid, list[Grid]]]]
    resolutions: list[tuple[int, int]] | None = None  # default: each scene's own
    triangle_budget: int = Field(DEFAULT_TRIANGLE_BUDGET, ge=1, le=100_000_000)
    frames: int = Field(15, ge=1, le=1000)  # measured frames per run, after the warm-up
    warmup: int = Field(2, ge=0, le=1000)
    # the 95% interval of each median time: order statistics or bootstrap (harness.timing)
    statistics: Literal[STATISTICS] = "order"
    reference: ReferenceSettings = ReferenceSettings()

    @field_validator("scenes")
    @classmethod
    def _some_scenes(cls, v):
        if not v:
            raise ValueError("must name at least one scene, or be 'all'")
        return v

    @field_validator("techniques")
    @classmethod
    def _some(cls, v):
        if v in ("all", "curves"):
            return v
        if not v:
            raise ValueError("must name at least one technique")
        for name, grids in v.items():
            if isinstance(grids, list) and not grids:
                raise ValueError(f"{name}: empty list of grids")
        return v

    @field_validator("resolutions")
    @classmethod
    def _res(cls, v):
        if v is not None and (not v or not all(16 <= x <= 8192 for r in v for x in r)):
            raise ValueError("must be a non-empty list of [width, height] in [16, 8192]")
        return v


def with_timing(exp: Experiment, **options) -> Experiment:
    """The experiment with command-line timing options (``frames``, ``warmup``,
    ``statistics``; None keeps the experiment's) validated as if the file had them; a bad
    value is a ConfigError naming the option, e.g. ``--frames: must be >= 1, got 0``."""
    given = {k: v for k, v in options.items() if v is not None}
    if not given:
        return exp
    try:
        return Experiment.model_validate({**exp.model_dump(), **given})
    except ValidationError as e:
        first = e.errors()[0]
        option = str(first["loc"][0])
        msg = first["msg"].removeprefix("Value error, ")
        raise ConfigError(f"--{option}: {msg}, got {given.get(option)!r}") from None


def load_experiment(path: str | Path) -> tuple[Experiment, object]:
    """Validate an experiment file; returns the model and the YAML root node (for lines).

    A technique's grid may be empty or null (its defaults), one grid (or curve), or a list of
    them."""
    path = Path(path)
    data, node = read_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: an experiment is a mapping with at least a 'techniques' key "
                          f"(see experiments/default.yaml), got {type(data).__name__}")
    techniques = data.get("techniques")
    if isinstance(techniques, dict):
        # each grid on its own, so an error names techniques.<name>... rather than the union
        data = {**data, "techniques": {name: _grids(path, node, name, grids)
                                       for name, grids in techniques.items()}}
    try:
        return Experiment.model_validate(data), node
    except ValidationError as e:
        raise ConfigError(format_validation_error(path, e, node)) from None


def _grids(path: Path, node, name: str, grids) -> Grid | list[Grid]:
    if grids is None:
        return Grid()
    items = grids if isinstance(grids, list) else [grids]
    checked = []
    for i, item in enumerate(items):
        prefix = ("techniques", name) + ((i,) if isinstance(grids, list) else ())
        try:
            checked.append(Grid.model_validate(item))
        except ValidationError as e:
            raise ConfigError(format_validation_error(path, e, node, prefix)) from None
    return checked if isinstance(grids, list) else checked[0]


def key_error(path: Path, node, loc: tuple, message: str) -> ConfigError:
    """A ConfigError for a key path found invalid after schema validation."""
    line = _line_of(node, loc) if node is not None else None
    where = f"{path}:{line}" if line else str(path)
    return ConfigError(f"{where}: {'.'.join(map(str, loc))}: {message}")
