"""Scene families (harness/scene/families.py), their sweep by an experiment's ``triangles``, and the
per-run counts (harness/scene/topology.py)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from helpers import ROOT

from harness import cli, config
from harness.scene import families
from harness.truth import metrics
from harness.scene import build_scene

SIZES = {"tessellation": [100, 1000, 10_000, 100_000],
         "instancing": [1000, 10_000, 100_000],
         "architecture": [1000, 10_000, 100_000],
         "foliage": [1000, 10_000, 100_000],
         "cards": [1000, 10_000, 100_000]}
CAMERA = {"position": [0, -19, 13], "target": [0, 0, 0], "up": [0, 0, 1], "yfov": 50,
          "near": 0.5, "far": 100}


def _triangles(family: config.Family) -> int:
    return sum(len(faces) for _, _, faces, _ in families.build(family))


@pytest.mark.parametrize("kind,triangles",
                         [(k, t) for k, sizes in SIZES.items() for t in sizes])
def test_family_lands_within_5_percent_below_its_target(kind, triangles):
    """Catches a family whose element counts drift from its geometry (a grid size, a picket
    count) so that its scenes are not the size the scale experiment plots them at, or exceed
    the budget checked on the target."""
    built = _triangles(config.Family(kind=kind, triangles=triangles))
    assert (1 - families.TOLERANCE) * triangles <= built <= triangles, built


@pytest.mark.parametrize("kind", list(SIZES))
def test_two_builds_are_bit_equal_and_the_seed_changes_the_layout(kind):
    """Catches unseeded randomness (a global generator, set ordering) that would change a
    scene, and so its references and run ids, from one run to the next."""
    family = config.Family(kind=kind, triangles=SIZES[kind][1])
    first, second = families.build(family), families.build(family)
    assert [name for name, *_ in first] == [name for name, *_ in second]
    for (_, v1, f1, _), (_, v2, f2, _) in zip(first, second):
        assert v1.dtype == np.float32 and v1.tobytes() == v2.tobytes()
        assert f1.tobytes() == f2.tobytes()
    other = families.build(family.model_copy(update={"seed": 1}))
    if kind != "tessellation":  # a box and a plane: nothing random
        assert any(a.tobytes() != b.tobytes() for (_, a, *_), (_, b, *_) in zip(first, other))


@pytest.mark.parametrize("triangles", [1000, 1_000_000])
def test_cards_are_cut_out_quads_of_leaf_texture_coordinates(triangles):
    """The cards family's cut-out parts are whole quads (two triangles on four corners) whose
    corners carry a plane's texture coordinates, and they hold most of its triangles; the
    trunks, branches and ground are opaque. Catches cards without texture coordinates, a
    corner order that maps the leaf across a diagonal, and a family of opaque cards."""
    scene = build_scene("c", _scene({"kind": "cards", "triangles": triangles}))
    assert scene.has_alpha and len(scene.alpha_masks) == 1
    cut = scene.face_mask == 0
    assert 0.7 < cut.mean() < 1  # trunks, branches and the ground stay opaque
    uv = scene.face_texcoords[cut].reshape(-1, 2, 3, 2)  # quads: two triangles each
    np.testing.assert_array_equal(uv[:, 0], [[[0, 1], [1, 1], [1, 0]]] * len(uv))
    np.testing.assert_array_equal(uv[:, 1], [[[0, 1], [1, 0], [0, 0]]] * len(uv))
    corners = scene.triangles[cut].reshape(-1, 2, 3, 3).astype(np.float64)
    # a quad is a parallelogram: its first corner + its third = its second + its fourth
    np.testing.assert_allclose(corners[:, 0, 0] + corners[:, 0, 2],
                               corners[:, 0, 1] + corners[:, 1, 2], atol=1e-5)


def test_cards_without_cutouts_are_the_same_triangles_opaque():
    """``cutouts: false`` keeps every triangle and drops the cut-outs, under a key of its own;
    ``cutouts: true`` is the default. Catches the key ignoring the switch (one reference for
    both scenes) and a switch that drops the cut-out parts' triangles."""
    family = {"kind": "cards", "triangles": 1000}
    cut, opaque = (build_scene("c", _scene({**family, "cutouts": on})) for on in (True, False))
    assert cut.has_alpha and not opaque.has_alpha
    np.testing.assert_array_equal(cut.triangles, opaque.triangles)
    assert cut.key != opaque.key
    assert cut.key == build_scene("c", _scene(family)).key


def _scene(family: dict, **extra) -> config.Scene:
    return config.Scene.model_validate({
        "resolution": [64, 64], "camera": CAMERA,
        "light": {"type": "directional", "direction": [-0.4, 0.3, -1]}, "family": family,
        **extra})


def test_tessellation_casts_the_same_shadow_at_every_size(gl_context):
    """Catches a tessellation whose refinement moves the caster or receiver (grid vertices
    off the box's faces, a receiver that grows with its cells): then the sweep measures a
    different shadow, not only more triangles. References compared on the pixels every size
    covers."""
    from harness.truth.reference import compute_reference

    refs = []
    for triangles in (100, 1000, 10_000):
        scene = build_scene(f"t{triangles}", _scene({"kind": "tessellation",
                                                     "triangles": triangles}))
        refs.append(compute_reference(scene, samples=4))
    covered = np.logical_and.reduce([r.covered for r in refs])
    assert covered.mean() > 0.5
    shadowed = 1 - refs[0].visibility[covered].mean()
    assert 0.01 < shadowed < 0.5  # there is a shadow to compare
    for r in refs[1:]:
        assert np.abs(r.visibility - refs[0].visibility)[covered].mean() < 0.002


@pytest.mark.slow
@pytest.mark.parametrize("name", ["architecture", "foliage"])
def test_shadow_volumes_at_1e5_match_the_reference_outside_edges(name, scene_at, evaluate):
    """Catches shadow volumes that break on many open, thin, non-manifold parts at 10^5
    triangles (per-triangle volumes miscounted, chunks dropped): every disagreement with the
    0/1 reference must sit in the edge band."""
    scene = scene_at(name, 96)
    assert scene.counts["triangles"] > 95_000
    e = evaluate(scene, "sv", {"buffer": "stencil", "method": "zfail"})
    assert e.row["status"] == "ok", e.row["error"]
    ref = e.reference.visibility
    wrong = (np.abs(e.visibility - ref) > 0.5) & e.mask
    band = metrics.edge_band(ref, mask=e.mask)
    assert (~band & e.mask).sum() > 0.05 * e.mask.sum()  # pixels outside the band to check
    assert not (wrong & ~band).any()


BOX = {"shape": "box", "size": [1, 1, 1], "translate": [0, 0, 1.5]}


@pytest.mark.parametrize("light,objects,expected", [
    # seen along (0.3, -0.2, 1) the box shows three faces: its outline is a hexagon
    ({"type": "directional", "direction": [-0.3, 0.2, -1]}, [BOX], (12, 1, 0, 6)),
    # straight above, a spot light sees only the top face: its four edges
    ({"type": "spot", "position": [0, 0, 10], "target": [0, 0, 0], "fov": 60}, [BOX],
     (12, 1, 0, 4)),
    # a plane adds two triangles, one open part and its four boundary edges
    ({"type": "directional", "direction": [-0.3, 0.2, -1]},
     [{"shape": "plane", "size": [10, 10]}, BOX], (14, 2, 1, 10)),
])
def test_counts_of_a_box_by_hand(light, objects, expected):
    """Catches counts that miss the merge of a part's vertices (a box's faces then look open),
    count the box's face diagonals (two faces facing the same way) or lose boundary edges."""
    scene = config.Scene.model_validate({"camera": CAMERA, "light": light, "objects": objects})
    counts = build_scene("box", scene).counts
    assert (counts["triangles"], counts["parts"], counts["open_parts"],
            counts["shadow_edges"]) == expected


def test_every_run_row_has_the_counts(evaluate):
    """Catches the counts columns missing from a run's row (score's cost columns)."""
    e = evaluate("box_plane", "sm", scene_file=ROOT / "scenes.yaml", resolution=(48, 32))
    assert e.row["status"] == "ok"
    assert {k: e.row[k] for k in ("triangles", "parts", "open_parts", "shadow_edges")} == {
        "triangles": 14, "parts": 2, "open_parts": 1, "shadow_edges": 10}


def test_the_reference_records_its_build_time_apart(tmp_path, monkeypatch, gl_context):
    """Catches the Mitsuba build time not recorded, counted outside the total, or lost when
    the reference is read back from the cache."""
    from harness.truth import reference

    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path))
    scene = build_scene("t", _scene({"kind": "tessellation", "triangles": 1000},
                                    resolution=[32, 32]))
    traced = reference.compute_reference(scene, samples=1)
    assert 0 < traced.build_seconds < traced.seconds
    cached = reference.compute_reference(scene, samples=1)
    assert cached.cached and cached.build_seconds == traced.build_seconds


def _experiment(tmp_path, scene_file: dict, **experiment):
    (tmp_path / "scenes.yaml").write_text(yaml.safe_dump({"scenes": scene_file}))
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump({"scene_file": "scenes.yaml", "techniques": {"sm": {}},
                                    **experiment}))
    return path


def _family_scene(**family):
    return {"resolution": [32, 32], "camera": CAMERA,
            "light": {"type": "directional", "direction": [-0.4, 0.3, -1]},
            "family": {"kind": "instancing", "triangles": "1e3", **family}}


def test_a_sweep_makes_one_scene_per_size_with_its_own_runs(tmp_path):
    """Catches sizes that collapse into one scene (same name or key: shared run ids and
    references) or scenes without a family swept too."""
    from harness.run.plan import plan_runs

    box = {"resolution": [32, 32], "camera": CAMERA,
           "light": {"type": "directional", "direction": [-0.3, 0.2, -1]}, "objects": [BOX]}
    path = _experiment(tmp_path, {"forest": _family_scene(), "box": box},
                       triangles=["1e3", "1e4"])
    plan = plan_runs(experiment_path=str(path), scene_file="unused", scenes=None,
                     techniques=None, overrides={})
    assert sorted(plan.scenes) == ["box", "forest@1e3", "forest@1e4"]
    assert len({r.run_id for r in plan.runs}) == len({r.scene_key for r in plan.runs}) == 3
    assert plan.scenes["forest@1e4"].counts["triangles"] == 9_992
    only = plan_runs(experiment_path=str(path), scene_file="unused", scenes=["forest@1e4"],
                     techniques=None, overrides={})
    assert list(only.scenes) == ["forest@1e4"]


def test_load_scene_takes_a_family_at_a_size_as_a_sweep_names_it(tmp_path):
    """``load_scene("forest@1e4")`` (the benchmarks' way to a scale scene) is the scene an
    experiment's ``triangles`` makes, the same key and so the same references; a size on a
    scene without a family, a size that is no whole number or one over the budget is a
    ConfigError. Catches a name@size built at the declared size, or under another key."""
    from harness.run.plan import plan_runs
    from harness.scene import load_scene

    box = {"resolution": [32, 32], "camera": CAMERA,
           "light": {"type": "directional", "direction": [-0.3, 0.2, -1]}, "objects": [BOX]}
    path = _experiment(tmp_path, {"forest": _family_scene(), "box": box}, triangles=["1e4"])
    scene_file = path.parent / "scenes.yaml"
    planned = plan_runs(experiment_path=str(path), scene_file="unused", scenes=None,
                        techniques=None, overrides={}).scenes["forest@1e4"]
    loaded = load_scene("forest@1e4", scene_file)
    assert loaded.name == "forest@1e4" and loaded.key == planned.key
    assert loaded.counts["triangles"] == 9_992
    for name, message in [("box@1e4", "has no family"), ("forest@lots", "whole number"),
                          ("forest@2e6", "more than the budget"), ("forest@5e2", "at least")]:
        with pytest.raises(config.ConfigError, match=message):
            load_scene(name, scene_file)


BAD_SCENES = {
    "unknown kind": (_family_scene(kind="city"), "scenes.bad.family"),
    "unknown parameter": (_family_scene(density=2), "scenes.bad.family.density"),
    "not a size": (_family_scene(triangles="many"), "scenes.bad.family.triangles"),
    "too small to land within 5%": (_family_scene(triangles=200),
                                    "scenes.bad.family.triangles"),
    "beyond the budget": (_family_scene(triangles="2e6"), "scenes.bad.family.triangles"),
}


@pytest.mark.parametrize("case", list(BAD_SCENES))
def test_bad_family_exits_2_naming_file_scene_and_key(case, tmp_path, capsys):
    """Catches a bad family that runs anyway or fails with a traceback, or writes output."""
    scene, keypath = BAD_SCENES[case]
    (tmp_path / "scenes.yaml").write_text(yaml.safe_dump({"scenes": {"bad": scene}}))
    out = tmp_path / "out"
    code = cli.main(["run", "--scene-file", str(tmp_path / "scenes.yaml"), "--out", str(out),
                     "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert str(tmp_path / "scenes.yaml") in err and keypath in err, err
    assert not out.exists()


@pytest.mark.parametrize("sizes,scenes,message", [
    (["1e3", "2e6"], None, "triangles.1: 2,000,000 triangles, more than the budget"),
    (["5e2"], None, "triangles.0: scene forest: the instancing family needs at least 1,000"),
    (["1e3"], ["box"], "triangles: sizes family scenes, but none"),
    ([], None, "triangles: must list at least one size"),
])
def test_bad_sizes_exit_2_naming_the_experiment_key(sizes, scenes, message, tmp_path, capsys):
    """Catches an experiment size the budget or the family cannot take, or sizes that apply
    to nothing, running anyway."""
    box = {"camera": CAMERA, "light": {"type": "directional", "direction": [0, 0, -1]},
           "objects": [BOX]}
    path = _experiment(tmp_path, {"forest": _family_scene(), "box": box}, triangles=sizes,
                       **({"scenes": scenes} if scenes else {}))
    out = tmp_path / "out"
    code = cli.main(["run", str(path), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert str(path) in err and message in err, err
    assert not out.exists()
