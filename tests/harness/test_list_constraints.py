"""What ``shadowbench list`` says a parameter allows is what its Params accept: a field
validator's restriction (ptsv's tile, a power of two in 2 .. 4) shows as the values it leaves,
for any technique, not as the bare bounds it narrows."""

from __future__ import annotations

import pytest
from pydantic import Field, ValidationError, field_validator

from harness.cli import listing
from harness.technique import Technique, TechniqueParams, registry


class PowersOfTwo(Technique):
    name = "powers"

    class Params(TechniqueParams):
        size: int = Field(4, ge=2, le=16)
        slices: int = Field(8, ge=1, le=64)
        wide: int = Field(1024, ge=1, le=4096)

        @field_validator("size", "wide")
        @classmethod
        def _power_of_two(cls, value: int) -> int:
            if value & (value - 1):
                raise ValueError(f"must be a power of two, got {value}")
            return value


def test_a_field_validator_shows_as_the_values_it_leaves():
    """Broken version caught (the old listing): ``int, >= 2, <= 16`` for size, though 3, 5, 6,
    7 ... are refused. A field no validator narrows keeps its bounds; a wide one says how many
    values pass."""
    rows = {name: allowed for name, _, allowed in listing.parameter_rows(PowersOfTwo)}
    assert rows == {"size": "int, one of 2, 4, 8, 16",
                    "slices": "int, >= 1, <= 64",
                    "wide": "int, one of 1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096"}
    with pytest.raises(ValidationError):
        PowersOfTwo.Params(size=6)


def test_list_shows_ptsvs_tile_as_2_or_4(capsys):
    """The issue's case: ``int, >= 2, <= 4`` listed, 3 refused at run time."""
    rows = {name: allowed for name, _, allowed in listing.parameter_rows(registry.get("ptsv"))}
    assert rows["tile"] == "int, one of 2, 4"
    lines = listing.techniques_lines()
    assert any(line.split()[:1] == ["tile"] and line.endswith("int, one of 2, 4")
               for line in lines), lines
