"""Config's check of types as written, below scene_schema and experiment_schema (and the base of
harness.technique's TechniqueParams): YAML's true and false are refused where a number, an
index or a name is expected."""

from __future__ import annotations

from typing import Any, Literal, get_args, get_origin

from pydantic import BaseModel, model_validator


def _admits_bool(annotation) -> bool:
    """Whether a field of this type may hold true or false (bool, Literal[True], a union or
    container with one of them)."""
    if annotation is bool or annotation is Any:
        return True
    if get_origin(annotation) is Literal:
        return any(isinstance(arg, bool) for arg in get_args(annotation))
    return any(_admits_bool(arg) for arg in get_args(annotation))


def _first_bool(value) -> bool | None:
    """The first boolean in ``value`` or the lists within it; None when there is none."""
    if isinstance(value, bool):
        return value
    for item in value if isinstance(value, (list, tuple)) else ():
        if (found := _first_bool(item)) is not None:
            return found
    return None


class TypesAsWritten(BaseModel):
    """A boolean where a number, an index or a name is expected is refused: pydantic would
    otherwise read ``true`` as 1 (``object: true`` as object 1). Strict mode everywhere would
    also refuse YAML's lists for tuples, so this checks booleans alone."""

    @model_validator(mode="before")
    @classmethod
    def _no_booleans(cls, data):
        for name, value in data.items() if isinstance(data, dict) else ():
            field = cls.model_fields.get(name)
            found = _first_bool(value) if field is not None else None
            if found is not None and not _admits_bool(field.annotation):
                raise ValueError(f"{name}: {str(found).lower()} is a boolean; a number, index or "
                                 "name is expected here")
        return data
