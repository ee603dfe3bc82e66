"""Absurd values of the length-like knobs are refused the same way on every map technique:
a bias (scene units) above 1e7, a slope_bias or normal_offset (texels) above 64, each bound
stated in the technique's table. Catches a technique whose knob has no upper bound (before:
normal_offset=1e9 on sm, pcf, csm and the cube map was accepted and took every shadow away;
seen failing with csm's normal_offset bound removed)."""

from __future__ import annotations

import re

import pytest

from harness import config
from harness.technique import registry
from harness.run import validate_params

from techniques.common.light_maps import MAX_BIAS, MAX_TEXELS

BOUNDS = {"bias": MAX_BIAS, "bias_min": MAX_BIAS, "bias_max": MAX_BIAS,
          "slope_bias": MAX_TEXELS, "normal_offset": MAX_TEXELS}
STATED = {MAX_BIAS: "1e7", MAX_TEXELS: "64"}
KNOBS = [(name, knob) for name, cls in registry.techniques().items()
         for knob in BOUNDS if knob in cls.Params.model_fields]


def test_every_map_technique_has_its_length_knobs():
    techniques = {name for name, _ in KNOBS}
    assert {"sm", "pcf", "csm", "mdsm", "silhouette", "psm", "lispsm", "gmnpr", "vsm"} <= techniques
    assert sum(knob == "normal_offset" for _, knob in KNOBS) == 9


@pytest.mark.parametrize("technique, knob", KNOBS)
def test_a_length_knob_above_its_bound_is_refused(technique, knob):
    bound = BOUNDS[knob]
    both = {"bias_min": 0.0} if knob == "bias_max" else {"bias_max": bound} if knob == "bias_min" \
        else {}
    assert validate_params(technique, {knob: bound, **both}, "here")[knob] == bound
    with pytest.raises(config.ConfigError, match=rf"here: {technique}\.{knob}: .*{bound:.0f}"):
        validate_params(technique, {knob: 1e9, **both}, "here")


@pytest.mark.parametrize("technique, knob", KNOBS)
def test_the_table_states_the_bound(technique, knob):
    doc = registry.get(technique).__doc__
    row = next(line for line in doc.splitlines()  # the table's row, not prose naming the knob
               if re.match(rf"\s*``{knob}``\s{{2,}}\S", line))
    assert row.rstrip().endswith(f".. {STATED[BOUNDS[knob]]}"), row
