"""Config's motion schema: the camera, light and object paths of a moving scene (harness/scene/motion.py
follows them)."""

from __future__ import annotations

from typing import Annotated, Union

from pydantic import AfterValidator, Field, field_validator

from .field_types import Strict, Vec3, vector_norm

MAX_ORBIT_DEG = 3600.0  # ten turns: more is a typo, not a path
MIN_DOLLY = -10.0  # backing away to eleven times the starting distance
Degrees = Annotated[float, Field(ge=-MAX_ORBIT_DEG, le=MAX_ORBIT_DEG)]


def _axis(v):
    if v is not None and vector_norm(v) == 0:
        raise ValueError("must not be the zero vector")
    return v


Axis = Annotated[Vec3 | None, AfterValidator(_axis)]


class ObjectMotion(Strict):
    """One object's rigid path (its array copies move with it): ``object`` is its index in
    ``objects`` or its ``name``. It spins by ``spin`` degrees about ``spin_axis`` through its
    own centre (the centre of its bounds as written), then orbits by ``orbit`` degrees about
    ``orbit_axis`` through ``centre`` (the centre of the scene's bounds as written unless
    given), then moves by ``translate``; an axis not given is the camera's up. Frame t is at
    t / (frames - 1) of each (harness/scene/motion.py)."""

    object: Union[Annotated[int, Field(ge=0)], str]
    spin: Degrees = 0.0
    spin_axis: Axis = None
    orbit: Degrees = 0.0
    orbit_axis: Axis = None
    centre: Vec3 | None = None
    translate: Vec3 = (0.0, 0.0, 0.0)


class Motion(Strict):
    """A moving scene: over ``frames`` frames the camera orbits its target about its up axis
    by ``camera_orbit`` degrees in total, the light (a directional light's direction; a spot
    light's position and target together; a point light's position) turns about the up axis
    through the centre of the scene's bounds by ``light_orbit`` degrees, and the camera moves
    toward its target by the fraction ``camera_dolly`` of its distance (negative: away);
    ``objects`` move along their own paths (:class:`ObjectMotion`). Frame t is at
    t / (frames - 1) of each path, so the first frame is the scene as written and the last
    ends the paths (harness/scene/motion.py)."""

    frames: int = Field(ge=2, le=1000)
    camera_orbit: Degrees = 0.0
    light_orbit: Degrees = 0.0
    camera_dolly: float = Field(0.0, ge=MIN_DOLLY)
    objects: list[ObjectMotion] = []

    @field_validator("camera_dolly")
    @classmethod
    def _short_of_the_target(cls, v):
        if v >= 1:
            raise ValueError(f"must be < 1: a dolly of 1 or more reaches or passes through the "
                             f"camera's target, got {v}")
        return v
