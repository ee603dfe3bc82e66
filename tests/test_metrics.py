"""Metrics against values computed by hand or by an independent implementation."""

import math

import numpy as np
import pytest

from harness import metrics


def test_mae_rmse_wrong_by_hand():
    ref = np.array([[1.0, 1.0], [0.0, 0.0]])
    v = np.array([[1.0, 0.25], [0.75, 0.0]])
    assert metrics.mae(v, ref) == pytest.approx((0 + 0.75 + 0.75 + 0) / 4)
    assert metrics.rmse(v, ref) == pytest.approx(math.sqrt((0.5625 * 2) / 4))
    assert metrics.wrong_pct(v, ref) == pytest.approx(50.0)
    mask = np.array([[True, True], [False, False]])
    assert metrics.mae(v, ref, mask=mask) == pytest.approx(0.375)
    assert metrics.wrong_pct(v, ref, mask=mask) == pytest.approx(50.0)


def test_shapes_are_checked():
    with pytest.raises(ValueError, match="shape"):
        metrics.mae(np.zeros((2, 2)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="mask"):
        metrics.mae(np.zeros((2, 2)), np.zeros((2, 2)), mask=np.ones((2, 2)))
    with pytest.raises(ValueError):
        metrics.flip(np.zeros((4, 4)), np.zeros((4, 4)))


def test_edge_band_of_a_vertical_edge():
    ref = np.ones((10, 10))
    ref[:, :5] = 0.0  # boundary between columns 4 and 5
    band = metrics.edge_band(ref, width=2)
    # boundary pixels are columns 4 and 5; two pixels either side gives columns 2..7
    assert np.array_equal(np.where(band.any(0))[0], np.arange(2, 8))
    assert band[:, 2:8].all()
    v = ref.copy()
    v[:, 5] = 0.0  # the technique's edge is one pixel off
    assert metrics.edge_mae(v, ref, width=2) == pytest.approx(10 / 60)
    assert metrics.mae(v, ref) == pytest.approx(0.1)


def test_edge_mae_default_band_is_two_pixels_either_side():
    """DESIGN's edge band is 2 px, and papers/gmnpr.py scores its near region with edge_mae's
    default. Catches that default changed to 1 px (the 1-px band, columns 3..6, would give
    2.5 / 40 = 0.0625). By hand: boundary columns 4 and 5, within 2 px (Chebyshev) columns
    2..7, 60 pixels; errors 0.5 in column 2 and 0.25 in column 6, 10 rows each."""
    ref = np.ones((10, 10))
    ref[:, :5] = 0.0
    v = ref.copy()
    v[:, 2] = 0.5  # 2 px from the boundary: inside the default band only
    v[:, 6] = 0.75  # 1 px from it: inside both
    assert metrics.edge_mae(v, ref) == pytest.approx((10 * 0.5 + 10 * 0.25) / 60)


def test_boundary_ignores_unmasked_neighbours():
    ref = np.ones((6, 6))
    mask = np.ones((6, 6), bool)
    mask[:, :3] = False
    ref[:, :3] = 0.0  # background, not a shadow edge
    assert not metrics.shadow_boundary(ref, mask=mask).any()


def test_levels_counts_distinct_values_in_band():
    ref = np.ones((8, 8))
    ref[:, :4] = 0.0
    v = ref.copy()
    v[:, 3] = 0.25
    v[:, 4] = 0.75
    v[0, 0] = 0.5  # outside the band (column 0 is 3+ px from the boundary): not counted
    assert metrics.levels(v, ref, width=1) == 4  # 0, 0.25, 0.75, 1


def test_acne_and_leak_count_outside_the_edge_band_over_all_compared_pixels():
    """Breaks caught: the band not left out (the dimmed band pixel would count), a
    denominator of lit (or shadowed) pixels only (would give 100/45), <= instead of < at the
    thresholds (the pixels exactly at 0.98 and 0.02 would count), unmasked pixels counted."""
    ref = np.ones((10, 10))
    ref[:, :5] = 0.0  # boundary columns 4, 5; width 2: band columns 2..7
    v = ref.copy()
    v[0, 9] = 0.97  # acne: lit, outside the band, below 0.98
    v[1, 9] = 0.98  # at the threshold: not acne
    v[3, 6] = 0.0  # inside the band: an edge error, not acne
    v[4, 0] = 0.03  # leak: shadowed, outside the band, above 0.02
    v[5, 1] = 0.02  # at the threshold: not a leak
    v[6, 2] = 1.0  # inside the band: not a leak
    v[9, 8] = 0.0  # not compared
    mask = np.ones((10, 10), bool)
    mask[9] = False
    assert metrics.acne_pct(v, ref, mask=mask) == pytest.approx(100 / 90)
    assert metrics.leak_pct(v, ref, mask=mask) == pytest.approx(100 / 90)
    # the band really is what keeps the edge pixels out: with a band of the boundary alone
    # (columns 4, 5) they count
    assert metrics.acne_pct(v, ref, mask=mask, width=0) == pytest.approx(200 / 90)
    assert metrics.leak_pct(v, ref, mask=mask, width=0) == pytest.approx(200 / 90)
    v[3, 5] = 0.0  # a boundary pixel itself: never outside the band
    assert metrics.acne_pct(v, ref, mask=mask, width=0) == pytest.approx(200 / 90)
    # a fractional reference pixel is neither fully lit nor fully shadowed
    ref[7, 9], v[7, 9] = 0.9375, 0.5
    assert metrics.acne_pct(v, ref, mask=mask) == pytest.approx(100 / 90)
    # thresholds are options
    assert metrics.acne_pct(v, ref, mask=mask, threshold=0.99) == pytest.approx(200 / 90)
    assert metrics.leak_pct(v, ref, mask=mask, threshold=0.01) == pytest.approx(200 / 90)
    assert math.isnan(metrics.acne_pct(v, ref, mask=np.zeros((10, 10), bool)))
    with pytest.raises(ValueError, match="shape"):
        metrics.leak_pct(np.zeros((2, 2)), np.zeros((2, 3)))


def test_edge_floor_is_the_reference_rounded_to_zero_or_one():
    """Breaks caught: the floor of V_ref against itself (0), rounding a fraction the wrong way
    (0.75 to 0 would give 0.75 per pixel), the whole image instead of the band."""
    ref = np.ones((4, 6))
    ref[:, :3] = 0.0
    ref[:, 3] = 0.75  # boundary: column 3 (fractional) and column 2 (a jump of 0.75)
    # width 1: band columns 1..4, 16 pixels; only column 3 errs, by 0.25
    assert metrics.edge_floor(ref, width=1) == pytest.approx(4 * 0.25 / 16)
    assert metrics.edge_floor(ref, width=1) == pytest.approx(
        metrics.edge_mae(np.where(ref >= 0.5, 1.0, 0.0), ref, width=1))
    mask = np.ones((4, 6), bool)
    mask[0] = False
    assert metrics.edge_floor(ref, mask=mask, width=1) == pytest.approx(3 * 0.25 / 12)
    assert metrics.edge_floor(np.round(ref)) == 0.0  # a 0/1 reference: a 0/1 answer is exact
    with pytest.raises(ValueError, match="mask"):
        metrics.edge_floor(ref, mask=np.ones((4, 6)))


def test_ssim_psnr_match_scikit_image():
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity

    rng = np.random.default_rng(3)
    ref = rng.random((32, 32))
    v = np.clip(ref + rng.normal(0, 0.1, ref.shape), 0, 1)
    assert metrics.ssim(v, ref) == pytest.approx(structural_similarity(ref, v, data_range=1.0))
    mse = np.mean((v - ref) ** 2)
    assert metrics.psnr(v, ref) == pytest.approx(10 * math.log10(1 / mse))
    assert metrics.psnr(v, ref) == pytest.approx(peak_signal_noise_ratio(ref, v, data_range=1))


def test_flip_zero_for_equal_images_and_grows_with_error():
    rng = np.random.default_rng(0)
    img = rng.random((32, 32, 3)).astype(np.float32)
    assert metrics.flip(img, img) == pytest.approx(0.0, abs=1e-6)
    small = metrics.flip(np.clip(img + 0.05, 0, 1), img)
    large = metrics.flip(np.clip(img + 0.4, 0, 1), img)
    assert 0 < small < large <= 1


def test_nonfinite_counts_nan_and_inf():
    assert metrics.nonfinite(np.array([1.0, np.nan]), np.array([[np.inf, -np.inf]])) == 3
    assert metrics.nonfinite(np.eye(4)) == 0


def test_shade_directional_lambert():
    from harness.scene import Light

    light = Light("directional", np.array([0.0, 0.0, -1.0]))
    normal = np.array([[[0.0, 0.0, 1.0], [0.0, 0.6, 0.8]]])
    pos = np.zeros((1, 2, 3))
    img = metrics.shade(np.array([[1.0, 0.5]]), normal, pos, np.array([[0.5, 1.0]]), light,
                        ambient=0.1)
    assert img[0, 0] == pytest.approx([0.5 * 1.1] * 3)
    assert img[0, 1] == pytest.approx([0.1 + 0.5 * 0.8] * 3)


def test_receives_light_turns_normals_toward_the_camera():
    from harness.scene import Light

    light = Light("directional", np.array([0.0, 0.0, -1.0]))  # light travels down
    position = np.zeros((1, 3, 3))
    normal = np.array([[[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0]]])
    above = metrics.receives_light(normal, position, light, camera_position=[0, 0, 5])
    below = metrics.receives_light(normal, position, light, camera_position=[0, 0, -5])
    # seen from above, the plane faces the light whichever way its stored normal points
    assert above.tolist() == [[True, True, False]]
    assert below.tolist() == [[False, False, False]]


def test_receives_light_only_inside_a_spot_cone():
    from harness.scene import Light

    light = Light("spot", np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, 10.0]), 60.0, 10.0)
    position = np.array([[[0.0, 0, 0], [5.0, 0, 0], [6.0, 0, 0]]])  # tan(30) * 10 = 5.77
    normal = np.broadcast_to([0.0, 0, 1], position.shape)
    got = metrics.receives_light(normal, position, light, camera_position=[0, -5, 5])
    assert got.tolist() == [[True, True, False]]
