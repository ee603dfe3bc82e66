"""Messages that name the user's input, never a library's internals or a temporary path: a glTF
buffer whose data URI holds fewer bytes than its byteLength, and ``compare --html`` to a path
that cannot be written."""

from __future__ import annotations

import base64
import json

import numpy as np
import yaml

from harness import cli
from harness.config import mesh_files

TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes() + \
    np.array([0, 1, 2, 0], np.uint16).tobytes()  # 36 bytes of positions, 8 of indices


def _gltf(payload: bytes) -> dict:
    """One triangle whose buffer (44 bytes by its byteLength) is the data URI of ``payload``."""
    return {
        "asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(TRIANGLE), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(payload).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "max": [1, 1, 0], "min": [0, 0, 0]},
                      {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]}


def _list(tmp_path, payload: bytes, monkeypatch, capsys) -> tuple[int, list[str], list[str]]:
    """``list``'s exit code, stderr lines and stdout lines on a scene of the glTF of
    ``payload``."""
    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(mesh_files, "_loaded", {})
    (tmp_path / "m.gltf").write_text(json.dumps(_gltf(payload)))
    scene = {"resolution": [32, 32], "camera": {"position": [0, -6, 4], "target": [0, 0, 0]},
             "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
             "objects": [{"shape": "plane", "size": [10, 10]},
                         {"shape": "mesh", "path": "m.gltf", "translate": [0, 0, 1]}]}
    (tmp_path / "scenes.yaml").write_text(yaml.safe_dump({"scenes": {"s": scene}}))
    code = cli.main(["list", "--scene-file", str(tmp_path / "scenes.yaml")])
    out = capsys.readouterr()
    return code, out.err.strip().splitlines(), out.out.splitlines()


def test_a_gltf_data_uri_shorter_than_its_byte_length_is_named(tmp_path, monkeypatch, capsys):
    """``list`` names the scene it cannot load on the scene's own line (and lists the rest).
    Catches the check of data URIs removed: trimesh's bare assert gave ``AssertionError:``
    (seen failing)."""
    code, err, out = _list(tmp_path, TRIANGLE[:20], monkeypatch, capsys)
    assert code == 0 and err == [], err
    [line] = [line for line in out if "CANNOT LOAD" in line]
    assert "m.gltf: buffers.0: its data URI holds 20 bytes, fewer than its byteLength of 44" \
        in line, line
    assert "AssertionError" not in line
    assert not list((tmp_path / "cache").rglob("*.npz"))  # refused, so not cached


def test_a_gltf_data_uri_of_its_byte_length_loads(tmp_path, monkeypatch, capsys):
    code, err, out = _list(tmp_path, TRIANGLE, monkeypatch, capsys)
    assert code == 0 and not any("CANNOT LOAD" in line for line in out), (err, out)


def test_compare_html_names_the_path_given_not_its_temporary_file(tmp_path, make_results,
                                                                   capsys):
    """Catches replace_atomically's error left as os.open raised it: ``/proc/.x.html.1a2b3c4d
    .tmp: No such file or directory`` (seen failing)."""
    folder = make_results(tmp_path / "a", [{"time_ms": 2.0}])
    code = cli.main(["compare", str(folder), str(folder), "--html", "/proc/x.html"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith("shadowbench: --html /proc/x.html: "), err
    assert ".tmp" not in err[0], err
