"""Alpha-tested casters in the techniques (issue 48): a card cut out by a checker over a ground
plane (tests/helpers.py's alpha_card_scene), each technique's V against the exact visibility
computed in the test (card_visibility: NumPy float64, each ground point moved along its ray to
the card's plane, sample_alpha there against the cutoff). The camera sees the ground only."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from harness.technique import Frame, registry

from helpers import (CARD_LIGHT, alpha_card_scene, card_crossing, card_uv, card_visibility,
                     checker, render_once, run_contract)

CHECKER = checker(8, 8)  # one texel a square: the cut runs along texel edges and corners


@pytest.fixture(scope="module")
def card_frames(gl_context):
    """The card scene's frame under the directional light and under the point light."""
    frames = {point: Frame(alpha_card_scene(CHECKER, point_light=point))
              for point in (False, True)}
    yield frames
    for frame in frames.values():
        frame.release()


def agreement(technique: str, frame, point_light: bool, **params) -> float:
    """Fraction of the covered pixels where the technique's V is within 0.5 of the exact."""
    cls = registry.get(technique)
    v = render_once(cls(cls.Params(**params)), frame).visibility
    g = frame.arrays
    exact = card_visibility(g.position, g.covered, CHECKER, 0.5, point_light)
    return float((np.abs(v - exact) <= 0.5)[g.covered].mean())


@pytest.mark.parametrize("backend", ["gl", "embree"])
def test_rt_agrees_with_the_exact_cut_out(card_frames, backend):
    """rt's any-hit rays pass the cut-out texels: V agrees with the exact visibility on at
    least 99.5 % of the pixels (the issue's bar; it measured 100 %), directional and point
    light. The card opaque would put 10.6 % of the pixels wrong. Catches rt ignoring alpha
    (a hit on a cut-out texel ending the ray: 89.4 %), the barycentric weights taken in
    another order, or the embree loop stopping at the first hit."""
    for point, frame in card_frames.items():
        if backend == "embree" and point:
            continue  # the same loop; one light is enough for the slower backend
        assert agreement("rt", frame, point, backend=backend) >= 0.995


@pytest.mark.parametrize("technique", ["sm", "pcf", "mdsm", "csm", "psm", "lispsm", "gmnpr"])
def test_map_techniques_cut_out_in_their_depth_pass(card_frames, technique):
    """Every map technique's depth pass discards the cut-out texels: at map 2048, V agrees
    with the exact visibility on at least 98 % of the pixels (sm 99.9 %, the rest at least
    99.8 %, measured). Catches the discard inverted (the holes cast and the card's squares
    do not), or the cut-out corners given other vertices' positions."""
    assert agreement(technique, card_frames[False], False, res=2048) >= 0.98


def test_vsm_cuts_out_in_its_page_rendering(card_frames):
    """vsm's page rendering discards the cut-out texels as the shared depth pass does: its
    pages resolve about a texel per pixel (finer than sm's 2048 map over the scene here), and V
    agrees with the exact visibility on at least 98 % of the pixels (measured: 99.4 %; the
    card opaque, 89.4 %).
    Catches the discard inverted (the holes cast, the squares do not) or the alpha test
    skipped (the card opaque)."""
    assert agreement("vsm", card_frames[False], False) >= 0.98


@pytest.mark.parametrize("cache", [True, False])
def test_vsm_counts_its_page_draws_alpha_texels(gl_context, cache):
    """vsm's fetches_per_px adds four texels per alpha test of the frame's page draws, per
    covered pixel: the first frame draws the card's pages (a whole number of tests, more than
    none); the second, the scene still, draws no page with the cache on (back to the one
    read per pixel, unfiltered) and the same pages again with it off (the same count). Catches
    the count left out of fetches_per_px, or counted when no page was drawn (a cached frame)."""
    cls = registry.get("vsm")
    outputs, _ = run_contract(cls, alpha_card_scene(CHECKER, size=48), cache=cache,
                              filter="none")
    covered = 48 * 48  # the camera sees ground only
    tests = [(out.fetches_per_px - 1) * covered / 4 for out in outputs]
    assert tests[0] > 0 and tests[0] == pytest.approx(round(tests[0]), abs=1e-6)
    assert tests[1] == pytest.approx(0 if cache else tests[0], abs=1e-6)


def test_izb_tests_the_texture_where_the_ray_meets_the_caster(card_frames):
    """izb at one sample tests each sample in the card's frustum at the point its ray to the
    light meets the card (the barycentric weights of that point, the corners' texture
    coordinates) and is left lit where the texel there is cut out: V agrees with the exact
    visibility on at least 99.5 % of the pixels, rt's bar (measured: 100 %; the card opaque, 89.4 %).
    Catches the cut-out test inverted, skipped (the card opaque), or the weights given to the
    wrong corners."""
    assert agreement("izb", card_frames[False], False) >= 0.995


@pytest.mark.parametrize("technique", ["sm", "pcf"])
def test_cube_maps_cut_out_in_every_face(card_frames, technique):
    """A point light's cube map cuts the card out as the single map does (sm 99.0 %, pcf
    99.5 % at faces of 2048, measured). Catches the cube's faces drawn without the cut-outs'
    textures bound, or without ALPHA_TEST."""
    assert agreement(technique, card_frames[True], True, res=2048) >= 0.98


def test_an_opaque_cut_out_changes_no_bit(gl_context):
    """A cut-out whose texture is all 255 (nothing cut) leaves sm's, rt's, vsm's and izb's V
    bit-equal to the same scene with no cut-out at all: the alpha path adds a test, never a
    change of depth, of the ray or of a sample's frustum test. Catches the cut-out corners
    given other vertices' positions, or the discard or izb's cut-out test inverted
    (everything cut)."""
    solid = alpha_card_scene(np.full((4, 4), 255, np.uint8), size=128)
    plain = dataclasses.replace(solid, parts=[dataclasses.replace(p, alpha=None, texcoords=None)
                                              for p in solid.parts])
    assert solid.has_alpha and not plain.has_alpha
    for technique in ("sm", "rt", "vsm", "izb"):
        cls = registry.get(technique)
        v = []
        for scene in (solid, plain):
            frame = Frame(scene)
            v.append(render_once(cls(cls.Params()), frame).visibility)
            frame.release()
        np.testing.assert_array_equal(v[0], v[1])


def test_rt_counts_one_alpha_test_per_ray_through_the_card(card_frames):
    """rt counts each ray's alpha tests: one per ray that crosses the card (its plane inside
    the card, from the test's own geometry), so alpha_tests_per_ray is that share of the
    traced rays (to the rays exactly on the card's border), and fetches_per_px is the mask's
    one read plus four texels per test. Catches the count left at 0, counted per triangle
    tested rather than per hit, or left out of fetches_per_px."""
    frame = card_frames[False]
    cls = registry.get("rt")
    out = render_once(cls(cls.Params()), frame)
    g = frame.arrays
    _, inside = card_crossing(g.position)
    share = inside[g.covered].mean()
    assert out.extra["alpha_tests_per_ray"] == pytest.approx(share, abs=2e-3)
    assert out.fetches_per_px == pytest.approx(1 + 4 * out.extra["alpha_tests_per_ray"])


@pytest.mark.parametrize("technique", ["sv", "ptsv", "silhouette"])
def test_edge_techniques_decline_unless_told_to_ignore(evaluate, technique):
    """sv, ptsv and silhouette decline a scene with cut-outs: skipped, the reason in error,
    the row's alpha column `declined`; with alpha: ignore they run and the row says
    `ignored`. Catches the declining check removed (the run would be ok and unmarked) or
    ignore not honoured (still skipped)."""
    scene = alpha_card_scene(CHECKER, size=48)
    declined = evaluate(scene, technique, samples=1).row
    assert declined["status"] == "skipped"
    assert "alpha-tested casters" in declined["error"] and "alpha: ignore" in declined["error"]
    assert declined["alpha"] == "declined"
    ignored = evaluate(scene, technique, {"alpha": "ignore"}, samples=1).row
    assert ignored["status"] == "ok" and ignored["alpha"] == "ignored"


def test_alpha_column_says_tested_or_none(evaluate):
    """A technique that treats cut-outs is `tested` on a scene with them and `none` on one
    without. Catches the column filled from the technique alone, not the scene."""
    scene = alpha_card_scene(CHECKER, size=48)
    plain = dataclasses.replace(scene, parts=[dataclasses.replace(p, alpha=None, texcoords=None)
                                              for p in scene.parts])
    assert evaluate(scene, "sm", samples=1).row["alpha"] == "tested"
    assert evaluate(plain, "sm", samples=1).row["alpha"] == "none"


def test_a_plugin_declines_cut_outs_unless_it_says_it_treats_them():
    """A technique that declares nothing (a plugin written before cut-outs) declines a scene
    with them, its reason without the `alpha: ignore` hint it has no parameter for; one that
    declares ``alpha_casters = True`` runs (`tested`). Catches a default that runs every
    technique on cut-outs, or a hint naming a parameter the plugin does not have."""
    from harness.technique import NotApplicable, Technique, TechniqueParams

    class Plugin(Technique):
        name = "plugin"

        class Params(TechniqueParams):
            res: int = 16

    class Treats(Plugin):
        alpha_casters = True

    scene = alpha_card_scene(CHECKER, size=16)
    assert Plugin.alpha_handling(Plugin.Params(), scene) == "declined"
    with pytest.raises(NotApplicable, match="alpha-tested casters") as declined:
        Plugin.check_alpha(Plugin.Params(), scene)
    assert "alpha: ignore" not in str(declined.value)
    assert Treats.alpha_handling(Treats.Params(), scene) == "tested"
    Treats.check_alpha(Treats.Params(), scene)


def test_sm_counts_the_depth_pass_alpha_texels(card_frames):
    """sm's fetches_per_px adds the depth pass's alpha texels: four per fragment of the card
    in the light's map, per covered pixel. The card's fragments are counted here from the
    map's own frustum: its corners projected into the map, the texel centres inside (NumPy).
    Catches the count left out, or counting every fragment (the ground's too)."""
    from harness.scene.transforms import fit_light

    frame = card_frames[False]
    cls = registry.get("sm")
    res = 256
    technique = cls(cls.Params(res=res))
    out = render_once(technique, frame)
    f = fit_light(frame.scene, res)  # the map's frustum (a function of the scene and res)
    card = frame.scene.parts[1]
    corners = np.c_[card.vertices, np.ones(len(card.vertices))] @ (f.proj @ f.view).T
    texels = (corners[:, :2] / corners[:, 3:] + 1) / 2 * res  # map coordinates, texels
    centres = np.stack(np.meshgrid(np.arange(res) + 0.5, np.arange(res) + 0.5), -1)
    lo, hi = texels.min(axis=0), texels.max(axis=0)  # the card is a rectangle in the map
    inside = np.all((centres > lo) & (centres < hi), axis=-1).sum()
    covered = frame.arrays.covered.sum()
    assert out.fetches_per_px == pytest.approx(1 + 4 * inside / covered, rel=1e-3)


@pytest.mark.parametrize("backend", ["gl", "embree"])
def test_rt_passes_a_stack_of_cut_outs(gl_context, backend):
    """Three copies of the card stacked 1e-3 apart: a ray through a hole of the first goes on
    through the holes of the next two, and stops at the first opaque texel. Its alpha tests,
    counted here from the cards' geometry (crossings inside each card, in order, until an
    opaque one), are rt's alpha_tests_per_ray on both backends, and V agrees with the exact
    visibility of the stack. Catches an any-hit that stops at the first cut-out (the stack's
    holes would count 1 test, not 3), or embree's tests left uncounted."""
    from harness.scene.alpha import sample_alpha

    frame = Frame(alpha_card_scene(CHECKER, size=128, card_copies=3))
    cls = registry.get("rt")
    out = render_once(cls(cls.Params(backend=backend)), frame)
    g = frame.arrays
    going, tests = np.ones(g.covered.shape, bool), np.zeros(g.covered.shape)
    for copy in range(3):
        hit, inside = card_crossing(g.position, copy=copy)
        tests += going & inside
        going &= ~(inside & (sample_alpha(CHECKER, card_uv(hit)) >= 0.5))
    frame.release()
    assert out.extra["alpha_tests_per_ray"] == pytest.approx(tests[g.covered].mean(), abs=3e-3)
    assert ((out.visibility > 0.5) == going)[g.covered].mean() >= 0.995


def part_visibility(position: np.ndarray, part) -> np.ndarray:
    """Exact visibility of points (..., 3) under one alpha-tested part (any shape and pose)
    and CARD_LIGHT, in NumPy float64: each point's ray to the light against each triangle
    (solving point + t to_light = corner 0 + b1 edge 1 + b2 edge 2), its texture coordinates
    at the weights, sample_alpha against the cutoff."""
    from harness.scene.alpha import sample_alpha

    p = position.reshape(-1, 3).astype(np.float64)
    shadowed = np.zeros(len(p), bool)
    corners = part.vertices[part.faces].astype(np.float64)
    for tri, uv in zip(corners, part.texcoords.astype(np.float64)):
        solve = np.linalg.inv(np.column_stack([tri[1] - tri[0], tri[2] - tri[0], CARD_LIGHT]))
        b1, b2, t = ((p - tri[0]) @ solve.T).T
        w = np.column_stack([1 - b1 - b2, b1, b2])
        inside = np.all(w >= 0, axis=1) & (t > 1e-6)
        shadowed |= inside & (sample_alpha(part.alpha.texture, w @ uv) >= part.alpha.cutoff)
    return np.where(shadowed, 0.0, 1.0).reshape(position.shape[:-1])


@pytest.mark.parametrize(("technique", "bar"), [("rt", 0.995), ("sm", 0.98)])
def test_a_moving_cut_out_is_cut_where_it_moved(gl_context, technique, bar):
    """The card spins 30 degrees between the two frames of a moving scene. At frame 1 the
    technique, prepared at frame 0 (rt: the card's bottom level with its texture coordinates,
    reached through its moved instance; sm: the scene's vertex buffer uploaded again), agrees
    with the exact visibility under the spun card (computed here from its moved corners) as
    on a still scene, and no longer with frame 0's (the spin tilts it about y). Catches sm's
    texture coordinates dropped when the moved scene mesh is built again, or rt's cut card
    left where it was (its instance not moved)."""
    motion = {"frames": 2, "objects": [{"object": "card0", "spin": 30}]}
    scene = alpha_card_scene(CHECKER, size=128, motion=motion)
    cls = registry.get(technique)
    frame = Frame(scene)
    moving = cls(cls.Params(**({"res": 2048} if technique == "sm" else {})))
    moving.prepare(frame)
    agree = []
    for index in (0, 1):
        frame.move_to(index)
        moving.update(frame)
        frame.meter.new_frame(True)
        v = moving.render(frame).visibility
        g = frame.arrays
        ground = g.covered & (np.abs(g.position[..., 2]) < 1e-3)
        exact = [part_visibility(g.position, frame.scene.parts[1]),
                 part_visibility(g.position, scene.parts[1])]  # spun, and as at frame 0
        agree.append([float((np.abs(v - e) <= 0.5)[ground].mean()) for e in exact])
    moving.release()
    frame.release()
    assert agree[0][1] >= bar and agree[1][0] >= bar  # each frame its own card
    assert agree[1][1] < 0.97  # the spin moved the shadow


@pytest.mark.parametrize("technique", list(registry.techniques()))
def test_every_technique_frees_what_the_cut_outs_made(gl_context, technique):
    """Every registered technique (those that decline, run with alpha: ignore) runs the
    contract on the card scene (prepare, update, two renders, release) and leaves no GL
    object behind: the cut-outs' textures, attribute buffer, rt's cut-out buffer and the
    counting program included. Catches the counting program or rt's cut-out buffer never
    released."""
    cls = registry.get(technique)
    params = {"alpha": "ignore"} if "alpha" in cls.Params.model_fields else {}
    outputs, _ = run_contract(cls, alpha_card_scene(CHECKER, size=48), **params)
    assert outputs is not None and outputs[-1].visibility.shape == (48, 48)
