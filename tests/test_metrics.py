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
