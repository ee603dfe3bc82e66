"""Scenes found from anywhere and meshes placed as users expect (issue 35): the shipped scenes
are the default outside the repository; ``list --scene NAME`` prints each object's bounds as
placed: scale, then rotate about x, then y, then z, then translate, never recentred."""


from harness.cli import main
from harness.config import shipped
from helpers import ROOT


PLACED = """\
scenes:
  placed:
    resolution: [32, 32]
    camera: {position: [0, -9, 6], target: [0, 0, 0], up: [0, 0, 1], yfov: 60, near: 0.1, far: 50}
    light: {type: directional, direction: [-0.3, 0.2, -1]}
    effects: [shadow]
    objects:
      - {shape: box, size: [1, 1, 1], scale: [2, 1, 1], rotate: [0, 0, 90], translate: [5, 0, 1]}
      - {shape: box, size: [1, 2, 3], rotate: [90, 0, 90]}
      - {shape: mesh, path: corner.obj, up: y, translate: [0, 0, 1]}
"""

# one triangle far from the origin, y up
CORNER = "v 10 0 0\nv 11 0 0\nv 10 1 0\nf 1 2 3\n"


def lines(capsys, *args) -> list[str]:
    assert main([str(a) for a in args]) == 0
    return capsys.readouterr().out.splitlines()


def test_the_shipped_scenes_are_the_default_outside_the_repository(tmp_path, monkeypatch,
                                                                   capsys):
    """From a folder with no scenes.yaml, list names the shipped file and plan finds box_plane;
    a scenes.yaml in the folder is read instead; a --scene-file that does not exist is exit 2.
    Catches the default taken relative to the working folder ("scenes.yaml: cannot read") and
    a missing explicit file listed as "no scene file" with exit 0."""
    monkeypatch.chdir(tmp_path)
    listed = lines(capsys, "list")
    assert f"scenes (from {ROOT / 'scenes.yaml'}):" in listed
    assert shipped.scene_file() == ROOT / "scenes.yaml"
    planned = lines(capsys, "plan", "--scenes", "box_plane", "--techniques", "sm")
    assert planned[:2] == ["1 runs (duplicate points merged) in 1 scenes, cost policy dynamic:",
                           "  box_plane 512x512: 1 runs: sm 1"]
    (tmp_path / "scenes.yaml").write_text(PLACED)
    (tmp_path / "corner.obj").write_text(CORNER)
    assert "scenes (from scenes.yaml):" in lines(capsys, "list")
    assert main(["list", "--scene-file", "missing.yaml"]) == 2
    assert capsys.readouterr().err == "shadowbench: --scene-file missing.yaml: no such file\n"


def test_objects_are_scaled_then_rotated_x_y_z_then_translated(tmp_path, capsys):
    """Bounds worked by hand. Box 1: scaled to 2 x 1 x 1, turned 90 degrees about z (x -> y),
    moved to (5, 0, 1): x 4.5..5.5, y -1..1, z 0.5..1.5 (rotated before scaling it would be
    x 4..6). Box 2, 1 x 2 x 3 turned 90 about x then 90 about z: extents 3, 1, 2 (z then x would
    give 2, 3, 1). The y-up triangle at x 10..11 turned so +y is +z and moved up 1: x 10..11,
    y 0, z 1..2, not recentred. Catches another order of the three, the rotations composed the
    other way, and a mesh recentred on its bounds."""
    (tmp_path / "scenes.yaml").write_text(PLACED)
    (tmp_path / "corner.obj").write_text(CORNER)
    shown = lines(capsys, "list", "--scene-file", tmp_path / "scenes.yaml", "--scene", "placed")
    assert shown[1:] == [
        "  0: box: bounds [4.5, -1, 0.5] .. [5.5, 1, 1.5], z up, 12 triangles, 1 parts",
        "  1: box: bounds [-1.5, -0.5, -1] .. [1.5, 0.5, 1], z up, 12 triangles, 1 parts",
        "  2: corner.obj: bounds [10, 0, 1] .. [11, 0, 2], file up y, 1 triangles, 1 parts",
        "  scene bounds [-1.5, -1, -1] .. [11, 1, 2]"]
