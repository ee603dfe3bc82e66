"""What a technique declares tunable, checked when it is registered, and the settings it implies.

A technique's ``tunable`` maps each parameter a user would set per scene (biases, a bias mode, a
filter's size, a fit) to the range ``shadowbench tune`` searches::

    tunable = {"bias": ("log", 1e-5, 10.0),          # a float, searched on a log scale
               "slope_bias": ("float", 0.0, 4.0),     # a float, searched linearly
               "q": ("choice", (4, 9, 16, 25)),       # one of these values
               "taps": ("int", 1, 8)}                 # an integer, searched linearly

and ``bias_terms`` names those of them that one scale multiplies together for the bias window
(:func:`scaled_bias`): how far every bias term may be scaled before acne or leaks appear.

Each range holds the parameter's default, so the defaults are a setting of the search (its
first trial); a quality knob is never tunable (its values are the curve the tuning walks).
"""

from __future__ import annotations

import math

KINDS = ("log", "float", "int", "choice")


def check_tunable(cls) -> None:
    """Check a technique's ``tunable`` and ``bias_terms`` like its quality knobs. Raises
    ValueError ``"<parameter>: <what is wrong>"``."""
    from pydantic import ValidationError

    if not isinstance(cls.tunable, dict):
        raise ValueError(f"must be a mapping {{parameter: (kind, ...)}}, got "
                         f"{type(cls.tunable).__name__}")
    fields = cls.Params.model_fields
    defaults = cls.Params().model_dump()
    for name, declared in cls.tunable.items():
        if name not in fields:
            raise ValueError(f"{name}: not a parameter of {cls.__name__}.Params; parameters: "
                             f"{', '.join(fields)}")
        if name in cls.quality_knobs:
            raise ValueError(f"{name}: is a quality knob (its values are the curve tune walks), "
                             "so it cannot also be tuned")
        values = _declared_values(name, declared)
        for value in values:
            try:
                cls.Params(**{**defaults, name: value})
            except ValidationError as e:
                first = e.errors()[0]
                if first["loc"]:  # the value itself; a check across parameters a trial may fail
                    reason = first["msg"].removeprefix("Value error, ")
                    raise ValueError(f"{name}: {value!r} is not valid: {reason}") from None
        default = defaults[name]
        kind = declared[0]
        inside = (default in values if kind == "choice"
                  else values[0] <= default <= values[1])
        if not inside:
            raise ValueError(f"{name}: the default {default!r} is outside {declared[1:]!r}; the "
                             "defaults must be a setting of the search")
    if not isinstance(cls.bias_terms, (tuple, list)):
        raise ValueError(f"bias_terms: must be a tuple of tunable parameters, got "
                         f"{type(cls.bias_terms).__name__}")
    for name in cls.bias_terms:
        if name not in cls.tunable or cls.tunable[name][0] == "choice":
            raise ValueError(f"bias_terms: {name!r} is not a tunable range (a bias term is "
                             "scaled, so it must be a number declared in tunable)")


def _declared_values(name: str, declared) -> list:
    """The values a declaration names (the two ends of a range, or the choices), checked."""
    if not isinstance(declared, (tuple, list)) or not declared or declared[0] not in KINDS:
        raise ValueError(f"{name}: needs (kind, ...) with kind one of {', '.join(KINDS)}, got "
                         f"{declared!r}")
    kind = declared[0]
    if kind == "choice":
        if len(declared) != 2 or not isinstance(declared[1], (tuple, list)) or len(declared[1]) < 2:
            raise ValueError(f"{name}: ('choice', (value, value, ...)) needs two values or more, "
                             f"got {declared!r}")
        values = list(declared[1])
        if len({repr(v) for v in values}) != len(values):
            raise ValueError(f"{name}: a choice listed more than once in {values!r}")
        return values
    if len(declared) != 3 or not all(_is_number(x) for x in declared[1:]):
        raise ValueError(f"{name}: ({kind!r}, low, high) needs two numbers, got {declared!r}")
    low, high = declared[1:]
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise ValueError(f"{name}: needs finite low < high, got {low!r}, {high!r}")
    if kind == "log" and low <= 0:
        raise ValueError(f"{name}: a log range needs low > 0, got {low!r}")
    if kind == "int" and not (float(low).is_integer() and float(high).is_integer()):
        raise ValueError(f"{name}: an int range needs whole ends, got {low!r}, {high!r}")
    return [low, high]


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def tunable_defaults(cls, params: dict) -> dict:
    """The values ``params`` (a point's settings) give the tunable parameters: the search's
    first trial."""
    return {name: params[name] for name in cls.tunable if name in params}


def scaled_bias(cls, params: dict, scale: float) -> dict:
    """``params`` with every bias term multiplied by ``scale``, each kept inside its declared
    range (so a scale past a range's end repeats that end: the window's curve saturates)."""
    out = dict(params)
    for name in cls.bias_terms:
        kind, low, high = cls.tunable[name]
        value = min(max(params[name] * scale, low), high)
        out[name] = round(value) if kind == "int" else value
    return out
