"""Config's value types, shared by the scene, motion and experiment schemas: bounded coordinates
and sizes, a field of view, square sample counts, and Strict, the base of every config model
(unknown keys refused, values as written)."""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
from pydantic import AfterValidator, ConfigDict, Field

from .limits import MAX_COORDINATE, MIN_FOV
from .types_as_written import TypesAsWritten

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


def power_of_two(value: int) -> int:
    """Validate a size that halves evenly down to 1 (a grid, a tile, a virtual map); a Params
    model takes it as ``field_validator(name)(power_of_two)``."""
    if value & (value - 1):
        raise ValueError(f"must be a power of two, got {value}")
    return value



class Strict(TypesAsWritten):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def vector_norm(v) -> float:
    return float(np.linalg.norm(np.asarray(v, dtype=float)))
