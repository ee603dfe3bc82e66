"""The scene file and experiment schema, validated at load. From the bottom up: limits,
yaml_source, cache_entry (verified cache entries), mesh_formats, mesh_files, types_as_written,
object_schema (the shapes), scene_schema, experiment_schema; beside them shipped (where the
shipped scenes and experiments lie); each name is ``harness.config.X``.

Every problem is a :class:`ConfigError` whose one-line message names the file, the key path
and (where the YAML has it) the line, e.g.
``scenes.yaml:12: scenes.box_plane.camera.yfov: must be in [0.01, 180), got 190``.
Unknown keys are errors, never silently ignored; so are a key given twice in one mapping
(both lines named) and an alias that refers to itself. The numbers' limits and their reasons
are in :mod:`harness.config.limits`.
"""

from .experiment_schema import (Experiment, Grid, ReferenceSettings, Scalar, SceneSettings,
                                load_experiment, with_timing)
from .limits import (DEFAULT_TRIANGLE_BUDGET, MAX_COORDINATE, MAX_DEPTH_RATIO, MAX_RUNS, MIN_FOV,
                     NAME_PATTERN)
from .field_types import (Coordinate, FieldOfView, Size, SquareInt, Strict, Vec3, power_of_two,
                          square_number)
from .alpha_files import (MAX_TEXTURE_SIDE, PATTERNS, Alpha, read_alpha_texture,
                          resolve_texture_path)
from .mesh_files import MeshParts, cache_root, mesh_parts, resolve_mesh_path
from . import shipped
from .motion_schema import MAX_ORBIT_DEG, MIN_DOLLY, Motion, ObjectMotion
from .object_schema import (Array, Box, Capsule, Cylinder, Lathe, MeshFile, Placed, Plane,
                            SceneObject, Sphere)
from .scene_schema import (LIGHT_TYPES, Camera, DirectionalLight, Family, Light, PointLight,
                           Scene, SceneFile, SpotLight, TriangleCount, check_resolution,
                           check_scenes, load_scenes)
from .types_as_written import TypesAsWritten
from .yaml_source import (MAX_YAML_NODES, ConfigError, check_name, key_error,
                          read_yaml, validation_error)
from .yaml_source import line_of  # the planner names the line of a bad grid point

__all__ = [
    "Alpha", "MAX_TEXTURE_SIDE", "PATTERNS", "read_alpha_texture", "resolve_texture_path",
    "Array", "Box", "Camera", "Capsule", "ConfigError", "Coordinate", "Cylinder",
    "DEFAULT_TRIANGLE_BUDGET", "DirectionalLight", "Experiment", "Family", "FieldOfView", "Grid", "Lathe",
    "LIGHT_TYPES", "Light", "MAX_COORDINATE", "MAX_DEPTH_RATIO", "MAX_ORBIT_DEG",
    "MAX_RUNS", "MAX_YAML_NODES", "MIN_DOLLY", "MIN_FOV", "MeshFile", "MeshParts", "Motion", "NAME_PATTERN",
    "ObjectMotion", "Placed", "Plane", "PointLight", "ReferenceSettings", "Scalar", "Scene",
    "SceneFile", "SceneSettings", "SceneObject", "Size", "Sphere", "SpotLight", "SquareInt",
    "Strict", "TriangleCount", "TypesAsWritten", "Vec3",
    "cache_root", "check_name", "check_resolution", "check_scenes", "key_error", "line_of",
    "load_experiment", "load_scenes", "mesh_parts", "read_yaml", "resolve_mesh_path", "shipped",
    "power_of_two", "square_number", "validation_error", "with_timing",
]
