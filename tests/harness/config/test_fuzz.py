"""Fuzzing the command line with hypothesis: scene and experiment documents of valid structure
with hostile values, and random mutations of the shipped files (values, keys, names, and the
YAML text itself). Whatever the document, `shadowbench run` ends with exit 0 or 2, prints no
traceback (exit 2: one line, or one per error of a file, up to five and a count), and writes
nothing outside --out.

What runs: a valid *scene* document is run for real, at 16x16 with one technique (sm), one
frame and one reference sample, so that hostile but valid geometry goes through the scene
builder, GL, Mitsuba and the writers; a valid *experiment* is only planned (execute replaced
by a stub) because a valid experiment may rightly ask for hours of work (8192^2 images, a
thousand frames) and the writers are the scene fuzz's.

Mesh files (issue 25) are fuzzed under a scene's mesh object: random bytes, OBJ files of
hostile lines, binary STL of hostile floats and lying counts, PLY headers of random counts,
and good files with bytes cut, changed or inserted; each is planned, not run.

Examples are derandomized (the same every run, so CI does not flake) and no example database
is written. About 40 s on 2 cores (see the test names for the counts).
"""

from __future__ import annotations

import contextlib
import copy
import io
import os
import shutil
import tempfile
from pathlib import Path
from unittest import mock

import pytest
import yaml
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from harness import cli, config
from harness import run as runner
from harness.config.yaml_source import MAX_LISTED_ERRORS
from helpers import ROOT

SHIPPED_SCENES = [ROOT / "scenes.yaml", ROOT / "experiments/papers/scenes.yaml",
                  ROOT / "experiments/hard_cases/scenes.yaml"]
SHIPPED_EXPERIMENTS = sorted(p for p in (ROOT / "experiments").rglob("*.yaml")
                             if p.name != "scenes.yaml")
MESHES = list((ROOT / "experiments/hard_cases").glob("*.obj"))
ESCAPE = "ESCAPE"  # replaced by an absolute path inside the example's folder, outside --out
SCENE_RUNS = 90
EXPERIMENT_RUNS = 120

SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])

# --- values --------------------------------------------------------------------------------------

hostile_numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 5e-324, 1e-300, 1e-7, 1e7, 1.0000001e7, 1e300, -1e300, -1]),
    st.integers(-10 ** 30, 10 ** 30))
escaping_names = st.sampled_from(["../../escape", ESCAPE, "../escape", "a/../../../escape"])
hostile_names = st.one_of(
    escaping_names,
    st.sampled_from(["x\" onerror=\"document.title='P'\"", ".hidden", "a/b", "", "nul\x00byte",
                     "line\nbreak", "<script>", "x" * 65]),
    st.text(max_size=12))
hostile_values = st.one_of(
    hostile_numbers, hostile_names, st.none(), st.booleans(),
    st.lists(hostile_numbers, max_size=4),
    st.dictionaries(st.text(max_size=6), hostile_numbers, max_size=2))

# --- documents of valid structure ---------------------------------------------------------------

coordinate = st.floats(-5, 5)
positive = st.floats(0.2, 4)


def vec3(values):
    return st.lists(values, min_size=3, max_size=3)


shapes = st.one_of(
    st.fixed_dictionaries({"shape": st.just("plane"), "size": st.lists(positive, min_size=2,
                                                                       max_size=2)}),
    st.fixed_dictionaries({"shape": st.just("box"), "size": vec3(positive),
                           "translate": vec3(coordinate), "rotate": vec3(st.floats(-90, 90))}),
    st.fixed_dictionaries({"shape": st.just("sphere"), "radius": positive,
                           "subdivisions": st.integers(1, 3), "translate": vec3(coordinate)}),
    st.fixed_dictionaries({"shape": st.just("cylinder"), "radius": positive, "height": positive,
                           "sections": st.integers(3, 16), "scale": positive}),
    st.fixed_dictionaries({"shape": st.just("capsule"), "radius": positive, "height": positive,
                           "sections": st.integers(3, 8),
                           "array": st.fixed_dictionaries({
                               "count": vec3(st.integers(1, 3)), "step": vec3(coordinate)})}),
    st.fixed_dictionaries({"shape": st.just("lathe"), "sections": st.integers(3, 12),
                           "profile": st.lists(st.tuples(st.floats(0, 2), st.floats(-2, 2))
                                               .map(list), min_size=2, max_size=5)}),
)
lights = st.one_of(
    st.fixed_dictionaries({"type": st.just("directional"), "direction": vec3(coordinate)}),
    st.fixed_dictionaries({"type": st.just("spot"), "position": vec3(st.floats(-8, 8)),
                           "target": vec3(coordinate), "fov": st.floats(5, 150)}),
    st.fixed_dictionaries({"type": st.just("point"), "position": vec3(st.floats(-8, 8))}))
scenes = st.fixed_dictionaries({
    "resolution": st.just([16, 16]),
    "camera": st.fixed_dictionaries({
        "position": vec3(st.floats(-10, 10)), "target": vec3(coordinate),
        "up": st.just([0, 0, 1]), "yfov": st.floats(10, 120), "near": st.floats(0.01, 1),
        "far": st.floats(20, 1000)}),
    "light": lights,
    "effects": st.sampled_from([["shadow"], ["shadow", "direct"]]),
    "objects": st.lists(shapes, min_size=1, max_size=4),
})
scene_names = st.one_of(st.from_regex(config.NAME_PATTERN, fullmatch=True), escaping_names,
                        hostile_names)
grid_values = st.one_of(st.integers(16, 4096), st.floats(0, 2), hostile_numbers, hostile_names)
experiments = st.fixed_dictionaries({
    "techniques": st.one_of(st.just("all"), st.dictionaries(
        st.sampled_from(["sm", "pcf", "mdsm", "sv", "psm", "nope", ""]),
        st.one_of(st.none(), st.fixed_dictionaries({}, optional={
            "product": st.dictionaries(st.sampled_from(["res", "bias", "k", "n"]),
                                       st.lists(grid_values, max_size=3), max_size=2),
            "set": st.dictionaries(st.sampled_from(["res", "bias", "k"]), grid_values,
                                   max_size=2)})),
        max_size=3)),
}, optional={
    "scenes": st.one_of(st.just("all"), st.lists(st.sampled_from(["box_plane", "pins", "nope"]),
                                                 max_size=2)),
    "resolutions": st.lists(st.lists(st.integers(-10, 10000), min_size=2, max_size=2),
                            max_size=2),
    "frames": st.integers(-2, 2000), "warmup": st.integers(-2, 2000),
    "reference": st.fixed_dictionaries({}, optional={"samples": st.integers(-1, 5000),
                                                     "seed": st.integers(-1, 10)}),
    "triangle_budget": st.integers(-1, 10 ** 9),
})

# --- mutations -----------------------------------------------------------------------------------


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _paths(value, prefix + (key,))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield from _paths(value, prefix + (index,))


def mutate(data, document):
    """Up to three changes at random places: a hostile value, a key removed, an unknown key
    added, a key renamed to a hostile name."""
    document = copy.deepcopy(document)
    for _ in range(data.draw(st.integers(0, 3), label="changes")):
        path = data.draw(st.sampled_from(list(_paths(document))), label="path")
        if not path:
            document = data.draw(hostile_values, label="document")
            continue
        parent = document
        for key in path[:-1]:
            parent = parent[key]
        op = data.draw(st.sampled_from(["value", "delete", "add", "rename"]), label="op")
        if op == "value":
            parent[path[-1]] = data.draw(hostile_values, label="value")
        elif op == "delete":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            name = data.draw(hostile_names, label="key")
            value = parent.pop(path[-1]) if op == "rename" else data.draw(hostile_values)
            parent[name] = value
    return document


def as_text(data, document) -> bytes:
    """The document as YAML, its bytes edited now and then (cut, inserted, a line doubled:
    YAML errors, duplicate keys, binary)."""
    text = yaml.safe_dump(document, sort_keys=False, allow_unicode=True).encode()
    if data.draw(st.integers(0, 4), label="edit text") == 0:
        at = data.draw(st.integers(0, len(text)), label="at")
        edit = data.draw(st.sampled_from(["cut", "insert", "double a line"]), label="edit")
        if edit == "cut":
            text = text[:at] + text[at + data.draw(st.integers(1, 20)):]
        elif edit == "insert":
            text = text[:at] + data.draw(st.binary(min_size=1, max_size=8)) + text[at:]
        else:
            lines = text.splitlines(keepends=True)
            i = min(at, len(lines) - 1) if lines else 0
            text = b"".join(lines[:i + 1] + lines[i:])
    return text


# --- the property ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fuzz_cache(tmp_path_factory):
    """References of fuzzed scenes go to a cache of their own, not the shared one."""
    previous = os.environ.get("SHADOWBENCH_CACHE")
    os.environ["SHADOWBENCH_CACHE"] = str(tmp_path_factory.mktemp("fuzz-cache"))
    yield
    if previous is None:
        del os.environ["SHADOWBENCH_CACHE"]
    else:
        os.environ["SHADOWBENCH_CACHE"] = previous


def run_and_check(root: Path, args: list[str]) -> int:
    """`shadowbench run ...` in this process: exit 0 or 2, no traceback, exit 2 in one line (a
    file's further errors one more line each, up to MAX_LISTED_ERRORS and a count), and no
    file outside ``root/out`` but the inputs in ``root/in``."""
    before = {p for p in root.rglob("*") if p.is_file()}
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = cli.main([a.replace(ESCAPE, str(root / "escape-absolute")) for a in args])
    text = err.getvalue()
    assert "Traceback" not in text, text
    assert code in (0, 2), text
    if code == 2:
        lines = text.strip().splitlines()
        assert 1 <= len(lines) <= MAX_LISTED_ERRORS + 1, text
        assert all(line.startswith("shadowbench: ") for line in lines), text
    event(f"exit {code}")
    written = {p for p in root.rglob("*") if p.is_file()} - before
    outside = [p for p in written if root / "out" not in p.parents]
    assert not outside, outside
    return code


def _example_folder():
    root = Path(tempfile.mkdtemp(prefix="fuzz-"))
    (root / "in").mkdir()
    return root


def _scene_run(root: Path, text: bytes, name) -> int:
    scene_file = root / "in" / "scenes.yaml"
    scene_file.write_bytes(text.replace(ESCAPE.encode(), str(root / "escape-absolute").encode()))
    for mesh in MESHES:
        shutil.copy(mesh, root / "in")
    experiment = root / "in" / "e.yaml"
    experiment.write_text(yaml.safe_dump({
        "scenes": [str(name).replace(ESCAPE, str(root / "escape-absolute"))],
        "techniques": {"sm": {"set": {"res": 64}}}, "resolutions": [[16, 16]], "frames": 1,
        "warmup": 0, "reference": {"samples": 1}}))
    return run_and_check(root, ["run", str(experiment), "--scene-file", str(scene_file), "--out",
                                str(root / "out"), "--quiet"])


@settings(max_examples=SCENE_RUNS, **SETTINGS)
@given(data=st.data())
def test_fuzz_scene_documents(data, gl_context, fuzz_cache):
    """One of the shipped scene files changed; a generated scene (valid structure) changed; or
    a generated scene as it is, under a hostile or a valid name. Catches any traceback or write
    outside --out that hostile scenes cause (with the name check and `results.inside` both
    disabled, it finds a scene named '../../escape' writing beside --out)."""
    source = data.draw(st.sampled_from(["shipped", "generated", "named"]), label="source")
    if source == "shipped":
        shipped = data.draw(st.sampled_from(SHIPPED_SCENES), label="file")
        document = mutate(data, yaml.safe_load(shipped.read_text()))
    else:
        name = data.draw(scene_names, label="name")
        document = {"scenes": {name: data.draw(scenes, label="scene")}}
        if source == "generated":
            document = mutate(data, document)
    names = (list(document["scenes"]) if isinstance(document, dict)
             and isinstance(document.get("scenes"), dict) and document["scenes"] else ["s"])
    name = data.draw(st.sampled_from(names), label="run scene")
    text = (as_text(data, document) if source != "named"
            else yaml.safe_dump(document, sort_keys=False, allow_unicode=True).encode())
    root = _example_folder()
    try:
        _scene_run(root, text, name)
    finally:
        shutil.rmtree(root)


@settings(max_examples=EXPERIMENT_RUNS, **SETTINGS)
@given(data=st.data())
def test_fuzz_experiment_documents_and_options(data, fuzz_cache):
    """Generated experiments or shipped ones changed, with hostile --techniques, --scenes and
    --set values, against the shipped scenes; valid ones are planned, not run."""
    if data.draw(st.booleans(), label="shipped"):
        shipped = data.draw(st.sampled_from(SHIPPED_EXPERIMENTS), label="file")
        document = yaml.safe_load(shipped.read_text())
        if isinstance(document.get("scene_file"), str):
            document["scene_file"] = str(shipped.parent / document["scene_file"])
    else:
        document = data.draw(experiments, label="experiment")
    document = mutate(data, document)
    options = []
    for option in ("--techniques", "--scenes"):
        if data.draw(st.integers(0, 3), label=option) == 0:
            options += [option, data.draw(st.one_of(hostile_names, st.just("sm,pcf")))]
    for _ in range(data.draw(st.integers(0, 2), label="--set")):
        technique = data.draw(st.sampled_from(["sm", "pcf", "x", ""]))
        key = data.draw(st.sampled_from(["res", "bias", "k", ""]))
        value = data.draw(st.one_of(hostile_names, hostile_numbers.map(str)))
        options += ["--set", f"{technique}.{key}={value}"]
    root = _example_folder()
    try:
        experiment = root / "in" / "e.yaml"
        experiment.write_bytes(as_text(data, document))
        planned = []
        with mock.patch.object(runner, "execute",
                               lambda plan, *a, **k: planned.append(plan) or 0), \
                mock.patch.object(runner, "read_manifest",
                                  lambda out: {"invocations": [{"runs_rendered": 0}]}):
            code = run_and_check(root, ["run", str(experiment), "--scene-file",
                                        str(SHIPPED_SCENES[0]), "--out", str(root / "out"),
                                        "--quiet", *options])
        assert (code == 0) == bool(planned)
    finally:
        shutil.rmtree(root)


# --- mesh files ----------------------------------------------------------------------------------

MESH_RUNS = 150
MESH_DEADLINE_MS = 20_000  # a hang is a failure, not a slow example on a busy machine
mesh_numbers = st.one_of(st.sampled_from(["nan", "inf", "-inf", "1e30", "1e39", "-0", "0x10", "",
                                          "1e-320", "abc"]),
                         st.floats(-3, 3).map(lambda x: f"{x:.3f}"),
                         st.integers(-3, 3).map(str))
mesh_indices = st.one_of(st.integers(-5, 8).map(str),
                         st.sampled_from(["0", "99999999999999999999", "1/1/1", "2//2", "x",
                                          "1.5", "-0"]))
obj_lines = st.one_of(
    st.lists(mesh_numbers, min_size=0, max_size=5).map(lambda v: "v " + " ".join(v)),
    st.lists(mesh_numbers, min_size=3, max_size=3).map(lambda v: "vn " + " ".join(v)),
    st.lists(mesh_indices, min_size=0, max_size=5).map(lambda f: "f " + " ".join(f)),
    st.sampled_from(["o a", "g b", "g", "# c", "", "vt 0 0", "l 1 2", "s off", "usemtl m",
                     " v 0 0 0", "v\t1\t0\t0", "f\t1\t2\t3"]),
    st.text(max_size=10))


def _good_obj(data) -> list[str]:
    return ["v 0 0 0", "v 1 0 0", "v 0 1 0", "v 0 0 1", "f 1 2 3", "f 1 2 4"]


@st.composite
def mesh_files(draw):
    """(suffix, bytes): random bytes under a mesh suffix; an OBJ of hostile lines around a good
    one; a binary STL of hostile floats with a true or lying count; a PLY with a header of
    random counts; a good PLY, STL or GLB with bytes cut, changed or inserted."""
    import struct

    import numpy as np
    import trimesh

    kind = draw(st.sampled_from(["bytes", "obj", "stl", "ply", "edited"]), label="kind")
    if kind == "bytes":
        return (draw(st.sampled_from([".obj", ".ply", ".stl", ".glb", ".gltf"])),
                draw(st.binary(max_size=300)))
    if kind == "obj":
        lines = _good_obj(draw) + draw(st.lists(obj_lines, max_size=8), label="lines")
        order = draw(st.permutations(range(len(lines))), label="order")
        return ".obj", "\n".join(lines[i] for i in order).encode("utf-8", "surrogatepass")
    if kind == "stl":
        count = draw(st.integers(0, 4), label="triangles")
        values = draw(st.lists(st.floats(width=32), min_size=12 * count, max_size=12 * count))
        records = b"".join(struct.pack("<12fH", *values[12 * i:12 * i + 12], 0)
                           for i in range(count))
        declared = draw(st.one_of(st.just(count), st.integers(0, 2 ** 32 - 1)), label="count")
        return ".stl", bytes(80) + struct.pack("<I", declared) + records
    if kind == "ply":
        vertices, faces = draw(st.integers(0, 5)), draw(st.integers(0, 5))
        body = draw(st.lists(mesh_numbers, max_size=30), label="body")
        return ".ply", (f"ply\nformat ascii 1.0\nelement vertex {vertices}\nproperty float x\n"
                        f"property float y\nproperty float z\nelement face {faces}\n"
                        "property list uchar int vertex_indices\nend_header\n"
                        + " ".join(body)).encode()
    suffix = draw(st.sampled_from([".ply", ".stl", ".glb"]), label="format")
    mesh = trimesh.Trimesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]),
                           [[0, 1, 2], [0, 1, 3], [1, 2, 3]], process=False)
    data = bytearray(mesh.export(file_type=suffix[1:]))
    for _ in range(draw(st.integers(1, 3), label="edits")):
        at = draw(st.integers(0, len(data)), label="at")
        edit = draw(st.sampled_from(["cut", "change", "insert"]), label="edit")
        if edit == "cut":
            del data[at:at + draw(st.integers(1, 40))]
        elif edit == "change" and at < len(data):
            data[at] = draw(st.integers(0, 255))
        else:
            data[at:at] = draw(st.binary(min_size=1, max_size=8))
    return suffix, bytes(data)


@settings(max_examples=MESH_RUNS, **{**SETTINGS, "deadline": MESH_DEADLINE_MS})
@given(mesh=mesh_files(), up=st.sampled_from(["z", "y"]))
def test_fuzz_mesh_files(mesh, up, fuzz_cache):
    """Mesh files of random bytes and of hostile structure under a scene's mesh object: exit 0
    (planned; execute replaced by a stub) or 2 in one line, never a traceback or a hang.
    Catches trimesh's own errors (IndexError, struct.error, KeyError ...) leaking out, and a
    lying STL count read as a file of that size."""
    suffix, data = mesh
    root = _example_folder()
    try:
        (root / "in" / f"m{suffix}").write_bytes(data)
        scene = {"resolution": [16, 16],
                 "camera": {"position": [0, -6, 4], "target": [0, 0, 0]},
                 "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
                 "objects": [{"shape": "plane", "size": [10, 10]},
                             {"shape": "mesh", "path": f"m{suffix}", "up": up}]}
        scene_file = root / "in" / "scenes.yaml"
        scene_file.write_text(yaml.safe_dump({"scenes": {"s": scene}}))
        planned = []
        with mock.patch.object(runner, "execute",
                               lambda plan, *a, **k: planned.append(plan) or 0), \
                mock.patch.object(runner, "read_manifest",
                                  lambda out: {"invocations": [{"runs_rendered": 0}]}):
            code = run_and_check(root, ["run", "--scene-file", str(scene_file), "--techniques",
                                        "sm", "--out", str(root / "out"), "--quiet"])
        assert (code == 0) == bool(planned)
        if planned:
            assert len(planned[0].scenes["s"].triangles) >= 3  # the plane's 2 and the mesh's
    finally:
        shutil.rmtree(root)
