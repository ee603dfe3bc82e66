"""Metrics against values computed by hand or by an independent implementation."""

import math

import numpy as np
import pytest

from harness.truth import metrics


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
    """The edge band of edge_mae is 2 px (docs/results.md), and papers/gmnpr.py scores its near
    region with edge_mae's default. Catches that default changed to 1 px (the 1-px band,
    columns 3..6, would give 2.5 / 40 = 0.0625). By hand: boundary columns 4 and 5, within 2 px
    (Chebyshev) columns 2..7, 60 pixels; errors 0.5 in column 2 and 0.25 in column 6, 10 rows
    each."""
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


# --- world flicker: a hand-built camera over the plane z = 0 ----------------------------------
# view_proj of a camera at height DEPTH above x = shift looking down -z at the plane z = 0:
# ndc x = x - shift, ndc y = y (a 2 x 2 patch of the plane fills the image), clip w = DEPTH.
# The plane is at one depth, so moving the camera sideways moves the image by exactly as much
# everywhere: one pixel is 2 / WIDTH in x.
WIDTH, HEIGHT, DEPTH = 8, 6, 5.0


def plane_camera(shift):
    view_proj = np.zeros((4, 4))
    view_proj[0] = [DEPTH, 0, 0, -DEPTH * shift]
    view_proj[1] = [0, DEPTH, 0, 0]
    view_proj[3] = [0, 0, -1, DEPTH]
    return view_proj


def plane_points(shift):
    """World points of the pixel centres (row 0 at the top) of the camera at ``shift``."""
    x = shift + (np.arange(WIDTH) + 0.5) / WIDTH * 2 - 1
    y = 1 - (np.arange(HEIGHT) + 0.5) / HEIGHT * 2
    xx, yy = np.meshgrid(x, y)
    return np.stack([xx, yy, np.zeros_like(xx)], axis=-1)


def world_args(shift_previous, shift):
    return dict(position=plane_points(shift), view_proj_previous=plane_camera(shift_previous),
                depth_previous=np.full((HEIGHT, WIDTH), DEPTH))


def lit_beyond(edge, points):
    """A shadow edge fixed on the plane: lit where x > ``edge``."""
    return (points[..., 0] > edge).astype(float)


def test_view_depth_is_the_distance_in_front_of_the_camera():
    """The hand-built camera's clip w is DEPTH on the plane and DEPTH - z above it. Catches
    the wrong row of the matrix (clip z)."""
    points = plane_points(0.0)
    points[0, 0, 2] = 1.5
    depth = metrics.view_depth(points, plane_camera(0.0))
    assert depth[0, 0] == DEPTH - 1.5 and (depth.ravel()[1:] == DEPTH).all()


def test_a_still_shadow_under_a_one_pixel_camera_move_has_no_world_flicker():
    """The camera moves one pixel sideways over a shadow edge fixed on the plane, the
    technique's edge a pixel and a bit off the truth's: at each pixel the edge jumps a
    pixel (pixel flicker 2 jumps in 48 pixels), but at each world point nothing changes
    (world flicker and changed % exactly 0). Catches a reprojection off by a pixel or
    flipped in x (it would compare other world points across the edges)."""
    before, now = plane_points(0.0), plane_points(0.25)
    v_prev, v = lit_beyond(0.05, before), lit_beyond(0.05, now)
    r_prev, r = lit_beyond(0.4, before), lit_beyond(0.4, now)
    assert metrics.flicker(v, v_prev, r, r_prev) == pytest.approx(2 * HEIGHT / (WIDTH * HEIGHT))
    args = world_args(0.0, 0.25)
    assert metrics.world_flicker(v, v_prev, r, r_prev, points=metrics.world_points(**args)) == 0.0
    assert metrics.world_changed_pct(v, v_prev, points=metrics.world_points(**args)) == 0.0


def test_world_flicker_by_hand_at_known_world_points():
    """A one-pixel move (frame t's column c is t-1's column c + 1; its last column leaves the
    view): 42 pixels compared, less one whose t-1 pixel is not compared (41). V changes at
    3 world points against a still truth (|1| each) and at 1 where the truth changes
    too (0): world flicker 3 / 41, changed % 4 / 41. Catches a mean over all pixels of t (48)
    or the truth's change left out (4 / 41)."""
    before, now = plane_points(0.0), plane_points(0.25)
    v_prev, r_prev = lit_beyond(0.05, before), lit_beyond(0.05, before)
    v, r = lit_beyond(0.05, now), lit_beyond(0.05, now)
    for row, col in [(0, 0), (2, 3), (5, 6), (4, 1)]:
        v[row, col] = 1 - v[row, col]
    r[4, 1] = v[4, 1]
    mask_previous = np.ones((HEIGHT, WIDTH), bool)
    mask_previous[3, 5] = False  # frame t's (3, 4)
    args = dict(world_args(0.0, 0.25), mask_previous=mask_previous)
    points = metrics.world_points(**args)
    assert metrics.world_flicker(v, v_prev, r, r_prev, points=points) == pytest.approx(3 / 41)
    points = metrics.world_points(**args)
    assert metrics.world_changed_pct(v, v_prev, points=points) == pytest.approx(100 * 4 / 41)


def test_disoccluded_pixels_are_left_out():
    """Where t-1 saw a surface 1% nearer (an occluder since moved away) the world point was
    hidden: its change is not counted, though V there differs wholly; 0.01% nearer is the same
    surface (float rounding) and counts: 1 change in 30 pixels (42 less 12 hidden), against
a still truth. Catches no depth test, or one tighter than 1e-4."""
    before, now = plane_points(0.0), plane_points(0.25)
    v_prev, v = lit_beyond(0.05, before), lit_beyond(0.05, now)
    r_prev, r = v_prev.copy(), v.copy()
    args = world_args(0.0, 0.25)
    args["depth_previous"][:, 2:4] = DEPTH * 0.99  # frame t's columns 1 and 2
    args["depth_previous"][0, 6] = DEPTH * (1 - 1e-4)  # frame t's (0, 5)
    v_prev[:, 2:4] = 1 - v_prev[:, 2:4]
    v_prev[0, 6] = 1 - v_prev[0, 6]
    points = metrics.world_points(**args)
    assert metrics.world_changed_pct(v, v_prev, points=points) == pytest.approx(100 * 1 / 30)
    points = metrics.world_points(**args)
    assert metrics.world_flicker(v, v_prev, r, r_prev, points=points) == pytest.approx(1 / 30)


def test_a_still_edge_under_a_fraction_of_a_pixel_does_not_flicker():
    """A move of 0.3 pixel: each world point lands 0.3 pixel past a centre of t-1, the nearest
    centre another point of the plane, and on column 3 the still edge (x = -0.1) lies between
    the two (x -0.05 at t, -0.125 in t-1). V lies within the range around each point: world
    flicker 0. An edge that moved 1.5 pixels on the plane (to x = 0.275) darkens columns 3
    and 4; column 4 (x 0.2, between t-1's lit 0.125 and 0.375) counts, column 3 does not: it
    lies between a dark and a lit centre, where no change can be told (the range's cost: a
    change within a pixel of an edge hides). 6 of 42. Catches the nearest pixel in place of
    the range (column 3 would count in the still case: 6 of 42, not 0)."""
    before, now = plane_points(0.0), plane_points(0.075)
    v_prev, v = lit_beyond(-0.1, before), lit_beyond(-0.1, now)
    args = world_args(0.0, 0.075)
    assert metrics.world_changed_pct(v, v_prev, points=metrics.world_points(**args)) == 0.0
    assert metrics.world_flicker(v, v_prev, v_prev, v_prev, points=metrics.world_points(**args)) == 0.0
    shimmered = lit_beyond(0.275, now)
    points = metrics.world_points(**args)
    assert metrics.world_changed_pct(shimmered, v_prev, points=points) == pytest.approx(100 * 6 / 42)


def test_world_flicker_checks_its_shapes():
    """Position, view-projection, depth and masks of the wrong shape, and frames of another
    shape than the world points, are errors. Catches a silent broadcast."""
    v = np.zeros((HEIGHT, WIDTH))
    args = world_args(0.0, 0.25)
    with pytest.raises(ValueError, match="position"):
        metrics.world_points(**{**args, "position": args["position"][..., :2]})
    with pytest.raises(ValueError, match="view_proj_previous"):
        metrics.world_points(**{**args, "view_proj_previous": np.eye(3)})
    with pytest.raises(ValueError, match="depth_previous"):
        metrics.world_points(**{**args, "depth_previous": v[:2]})
    with pytest.raises(ValueError, match="mask"):
        metrics.world_points(**args, mask_previous=v)
    points = metrics.world_points(**args)
    with pytest.raises(ValueError, match="shape"):
        metrics.world_flicker(v, v[:, :2], v, v, points=points)
    with pytest.raises(ValueError, match="world points"):
        metrics.world_changed_pct(v[:2], v[:2], points=points)


def test_psnr_of_identical_images_is_inf_without_a_warning():
    """Before: scikit-image's 'divide by zero encountered' RuntimeWarning."""
    import warnings

    from harness.truth import metrics

    v = np.linspace(0, 1, 64, dtype=np.float32).reshape(8, 8)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert metrics.psnr(v, v) == float("inf")
    assert metrics.psnr(v, np.clip(v + 0.1, 0, 1)) == pytest.approx(
        10 * np.log10(1 / np.mean((np.clip(v + 0.1, 0, 1) - v) ** 2)))
