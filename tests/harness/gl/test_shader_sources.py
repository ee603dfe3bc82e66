"""A shader's expanded source is kept for the process while the files it read are unchanged
(harness/gl/shaders.py preprocess): every run makes its technique's programs anew."""

from __future__ import annotations

from pathlib import Path

from harness.gl.shaders import GLSL_VERSION, preprocess


def _files(tmp_path: Path) -> Path:
    (tmp_path / "common.glsl").write_text("float shared() { return 1.0; }\n")
    main = tmp_path / "main.frag.glsl"
    main.write_text('#include "common.glsl"\nvoid main() {}\n')
    return main


def test_an_unchanged_shader_is_read_once(tmp_path, monkeypatch):
    """The second expansion reads no file, and defines still head each source. Catches the
    files read and expanded again for every program (45 % of making one)."""
    main = _files(tmp_path)
    first = preprocess(main, {"K": 4})
    reads = []
    real_read = Path.read_text
    monkeypatch.setattr(Path, "read_text", lambda p, *a, **k: reads.append(p) or real_read(p, *a, **k))
    again = preprocess(main, {"K": 9})
    assert reads == []
    assert first.replace("#define K 4", "#define K 9") == again
    assert again.startswith(f"{GLSL_VERSION}\n#define K 9\n#line 1\n")
    assert "float shared()" in again and "#include" not in again


def test_an_edited_include_is_read_again(tmp_path):
    """An include edited in place between two programs: the second has the new text. Catches
    an expansion kept by the shader's own file alone."""
    main = _files(tmp_path)
    assert "return 1.0" in preprocess(main)
    (tmp_path / "common.glsl").write_text("float shared() { return 2.0; }\n")
    assert "return 2.0" in preprocess(main)
