"""The one sampling rule of alpha-tested casters (issue 48, harness/scene/alpha.py): bilinear at
mip level 0, repeat wrap, texel centres at half-integers, against hand computations; the
procedural patterns' cut-outs; and the reference's Dr.Jit port of the rule against it."""

from __future__ import annotations

import numpy as np
import pytest

from harness.scene.alpha import AlphaMask, pattern_texture, sample_alpha

# 2 rows, 3 columns: texel (i, j) is centred at ((j + 0.5) / 3, (i + 0.5) / 2)
T = np.array([[0, 30, 60], [90, 120, 150]], np.uint8)


@pytest.mark.parametrize("uv, by_hand", [
    # texel centres: the texel itself
    ((0.5 / 3, 0.25), 0), ((1.5 / 3, 0.25), 30), ((2.5 / 3, 0.75), 150),
    # on the edge half way between two centres: their mean
    ((1 / 3, 0.25), (0 + 30) / 2), ((1.5 / 3, 0.5), (30 + 120) / 2),
    # inside: x = 0.6 * 3 - 0.5 = 1.3, y = 0.4 * 2 - 0.5 = 0.3; top 30 * 0.7 + 60 * 0.3 = 39,
    # bottom 120 * 0.7 + 150 * 0.3 = 129; 39 * 0.7 + 129 * 0.3 = 66
    ((0.6, 0.4), 66),
    # the image's corner (0, 0): half way between the last and first columns and rows (repeat)
    ((0.0, 0.0), (150 + 90 + 60 + 0) / 4),
    # a texel corner inside: the mean of the four around it
    ((1 / 3, 0.5), (0 + 30 + 90 + 120) / 4),
    # repeat: whole numbers added to u and v change nothing
    ((0.6 + 2, 0.4 - 3), 66), ((-1.0, 5.0), 75),
    # the right edge (u = 1: x = 2.5) is half way between the last column and the first
    ((1.0, 0.25), (60 + 0) / 2),
])
def test_the_rule_against_a_hand_computation(uv, by_hand):
    """Catches texel centres at integers (uv (0.5 / 3, 0.25) would read between texels 0 and
    1: 15, not 0), clamp instead of repeat ((0, 0) would read texel (0, 0): 0, not 75; the
    right edge (u = 1) 60, not 30), and v upward (row 1 where row 0 is meant)."""
    assert sample_alpha(T, np.array(uv)) * 255 == pytest.approx(by_hand, abs=1e-9)


def test_the_cutoff_is_inclusive():
    """A surface is there where alpha >= cutoff. Catches a strict comparison."""
    mask = AlphaMask(T, 30 / 255, "t")
    assert mask.opaque(np.array([1.5 / 3, 0.25])) and not mask.opaque(np.array([0.5 / 3, 0.25]))


@pytest.mark.parametrize("pattern, there", [
    ("checker", lambda i, j: (i + j) % 2 == 0),
    ("bars", lambda i, j: j % 2 == 0),
])
def test_a_checker_and_bars_cut_out_their_texels_squares(pattern, there):
    """At cutoff 1/2 the checker's and bars' cut-outs are their texels' squares exactly (what
    the docs and the fence scene promise), away from the texel edges (ties). Catches a
    pattern of other texels, and the rule's centre at integers (which shifts the squares by
    half a texel)."""
    w, h = 8, 6
    mask = AlphaMask(pattern_texture(pattern, w, h), 0.5, pattern)
    uv = np.random.default_rng(0).uniform(-1, 2, (20000, 2))
    x, y = uv[:, 0] * w, uv[:, 1] * h
    away = (np.abs(x - np.round(x)) > 1e-6) & (np.abs(y - np.round(y)) > 1e-6)
    expected = there(np.floor(y).astype(int) % h, np.floor(x).astype(int) % w)
    assert (mask.opaque(uv) == expected)[away].all()


def test_the_reference_port_of_the_rule_agrees_with_numpy():
    """The reference's Dr.Jit port (float64 gathers) decides as sample_alpha does at random
    uv, wrapping included, on two masks of different sizes. Catches a port that clamps, swaps
    rows and columns, or reads another mask's texels."""
    import drjit as dr

    from harness.truth import cutouts
    from harness.truth import reference as ref_mod

    mi = ref_mod.mitsuba_module("llvm_ad_rgb")
    rng = np.random.default_rng(1)
    masks = (AlphaMask(rng.integers(0, 256, (5, 7), dtype=np.uint8), 0.5, "a"),
             AlphaMask(rng.integers(0, 256, (3, 4), dtype=np.uint8), 0.3, "b"))

    class Scene:
        alpha_masks = masks

    table = cutouts.cutout_table(mi, Scene)
    uv = rng.uniform(-2, 3, (4000, 2)).astype(np.float32)
    which = rng.integers(0, 2, len(uv))
    got = np.asarray(cutouts.surface_there(mi, table, mi.Int32(which), mi.Point2f(uv[:, 0], uv[:, 1]),
                                    dr.full(mi.Bool, True, len(uv))))
    alpha = np.choose(which, [masks[0].alpha(uv), masks[1].alpha(uv)])
    cutoff = np.array([m.cutoff for m in masks])[which]
    assert (got == (alpha >= cutoff)).all()
