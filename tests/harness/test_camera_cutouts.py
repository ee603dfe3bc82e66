"""The camera sees through cut-outs (issue 48): the G-buffer's camera pass alpha-tests as the
light's depth passes do, and the reference's camera and coverage rays go on past cut-out hits
as its shadow rays do. A checker card straight below the camera over a ground plane
(tests/helpers.py's alpha_card_scene seen from CARD_OVER_CAMERA), against what each pixel
centre's camera ray sees, computed here in float64: the ray to the card's plane, the sampling
rule there, else on to the ground."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from harness.scene.alpha import sample_alpha
from harness.technique import Frame
from harness.truth.reference import compute_reference

from helpers import CARD_HEIGHT, CARD_OVER_CAMERA, CARD_SIZE, alpha_card_scene, card_uv, checker

# from below: the card's shadow rays meet the ground (V = 0 on the card), the ground's meet
# nothing (V = 1 where the camera sees it, through the card's holes too)
UPWARD_LIGHT = {"type": "directional", "direction": [0.1, 0.0, 1.0]}

SIZE = 96
CHECKER = checker(16, 4)  # 4 x 4 squares of 4 x 4 texels: the bilinear rule's 0.5 at their edges
EDGE = 1e-3  # a pixel centre's ray this near the card's border (scene units): a tie
TIE = 0.02  # alpha this near the cutoff (float32 uv over 16 texels): a tie


def seen(size: int, ground: bool = True, at_pixel=(0.5, 0.5)):
    """(position (H, W, 3), covered, tie) of the camera ray through each pixel's point
    ``at_pixel`` (its centre by default), image rows top first: the card where its alpha is at
    or above the cutoff, else the ground (with ``ground``; 10 x 10 at z = 0), else nothing."""
    cam = CARD_OVER_CAMERA
    origin = np.asarray(cam["position"], np.float64)
    half = math.tan(math.radians(cam["yfov"]) / 2)
    ndc_x, ndc_y = np.meshgrid(2 * (np.arange(size) + at_pixel[0]) / size - 1,
                               1 - 2 * (np.arange(size) + at_pixel[1]) / size)
    # looking down -z with y up: right is +x
    d = np.stack([ndc_x * half, ndc_y * half, -np.ones_like(ndc_x)], -1)

    def at(z):
        return origin + ((z - origin[2]) / d[..., 2])[..., None] * d

    card = at(CARD_HEIGHT)
    offset = np.abs(card[..., :2] - [CARD_HEIGHT, 0.0])
    inside = np.all(offset <= CARD_SIZE / 2, -1)
    alpha = sample_alpha(CHECKER, card_uv(card))
    there = inside & (alpha >= 0.5)
    floor = at(0.0)
    on_ground = ground & np.all(np.abs(floor[..., :2]) <= 5, -1)
    tie = (np.abs(offset - CARD_SIZE / 2).min(-1) < EDGE) | (inside & (np.abs(alpha - 0.5) < TIE))
    return np.where(there[..., None], card, floor), there | on_ground, tie


def card_seen(size: int):
    """Whether each pixel sees the card, and whether all of it does or none (its centre and
    its corners agree, off ties)."""
    at = [seen(size, True, p) for p in ((0.5, 0.5), (0, 0), (1, 0), (0, 1), (1, 1))]
    card = [a[0][..., 2] > 0 for a in at]
    return card[0], np.all([c == card[0] for c in card], 0) & ~np.any([a[2] for a in at], 0)


def card_only(scene):
    """The scene without its ground: a ray through a hole meets nothing."""
    return dataclasses.replace(scene, parts=scene.parts[1:])


@pytest.fixture(scope="module")
def scene():
    return alpha_card_scene(CHECKER, size=SIZE, camera=CARD_OVER_CAMERA)


def test_the_gbuffer_sees_the_ground_through_the_holes(gl_context, scene):
    """The G-buffer's positions are the card's where it is there and the ground's through its
    holes (about half the card's pixels), as computed here. Catches the camera pass without
    the discard (every card pixel at the card's height)."""
    frame = Frame(scene)
    g = frame.arrays
    frame.release()
    position, covered, tie = seen(SIZE)
    through = covered & (position[..., 2] == 0) & np.all(
        np.abs(position[..., :2] - [CARD_HEIGHT, 0.0]) < CARD_SIZE / 2 - 0.1, -1)
    assert through.sum() > SIZE * SIZE // 20
    assert np.array_equal(g.covered, covered)
    assert np.abs(g.position - position)[covered & ~tie].max() < 1e-4


@pytest.mark.parametrize("variant", ["llvm_ad_rgb", "scalar_rgb"])
def test_coverage_through_the_holes_is_the_same_on_both_sides(gl_context, scene, variant):
    """The card without the ground: a pixel is covered where its centre's ray meets the card
    where it is there, in the G-buffer and in the reference alike, as computed here (off
    ties). Catches the reference's coverage or
    camera rays stopping at the card (every pixel inside it covered), and the G-buffer's missing discard."""
    size = SIZE if variant == "llvm_ad_rgb" else SIZE // 4
    lone = card_only(scene if size == SIZE else
                     alpha_card_scene(CHECKER, size=size, camera=CARD_OVER_CAMERA))
    _, covered, tie = seen(size, ground=False)
    ref = compute_reference(lone, samples=1, use_cache=False, variant=variant)
    if variant == "llvm_ad_rgb":
        frame = Frame(lone)
        gl_covered = frame.arrays.covered
        frame.release()
        assert np.array_equal(gl_covered, covered)
    holes = ~covered & np.all(np.abs(seen(size)[0][..., :2] - [CARD_HEIGHT, 0.0])
                              < CARD_SIZE / 2, -1)
    assert holes.sum() > size * size // 20
    assert np.array_equal(ref.covered[~tie], covered[~tie])


def test_the_reference_samples_see_the_ground_through_the_holes():
    """Lit from below, a sample on the card is shadowed by the ground and one on the ground
    is not: the reference's V (16 samples) is 0 on the pixels that see only the card where it
    is there and 1 on those that see only ground, through the holes too, as computed here.
    Catches the reference's camera rays stopping at the card (its holes then 0)."""
    lit_below = alpha_card_scene(CHECKER, size=SIZE, camera=CARD_OVER_CAMERA,
                                 light=UPWARD_LIGHT)
    ref = compute_reference(lit_below, samples=16, use_cache=False, variant="llvm_ad_rgb")
    card, whole = card_seen(SIZE)
    _, _, tie = seen(SIZE)
    holes = whole & ~card & np.all(np.abs(seen(SIZE)[0][..., :2] - [CARD_HEIGHT, 0.0]) < 1, -1)
    assert holes.sum() > SIZE * SIZE // 40
    assert np.array_equal(ref.visibility[whole], np.where(card, 0.0, 1.0)[whole])
