"""Errors that point at the mistake (issue 35): an unknown key first, at its own line, with the
closest key the schema allows there; every error of a file listed with its line (up to five)."""

from pathlib import Path

from harness.cli import main

TYPO = """\
scenes:
  bunny:
    resolution: [64, 64]
    camera: {position: [0, -6, 4], target: [0, 0, 0], up: [0, 0, 1], yfov: 60, near: 0.1, far: 9}
    effects: [shadow]
    ligth: {type: directional, direction: [-0.3, 0.2, -1]}
    objects:
      - {shape: plane, size: [10, 10]}
"""

THREE = """\
scenes:
  one:
    resolution: [64, 64]
    camera: {position: [0, -6, 4], target: [0, 0, 0], up: [0, 0, 1], yfov: 260, near: 0.1, far: 9}
    light: {type: directional, direction: [-0.3, 0.2, -1]}
    effects: [shadow]
    objects:
      - {shape: plane, size: [10, 10], colour: red}
      - {shape: sphere, radius: -1, tranlate: [0, 0, 1]}
"""


def errors(tmp_path: Path, capsys, text: str, *command) -> list[str]:
    path = tmp_path / "scenes.yaml"
    path.write_text(text)
    code = main([*command, "--scene-file", str(path)])
    err = capsys.readouterr().err
    assert code == 2, err
    return [line.replace(str(path), "F") for line in err.splitlines()]


def test_a_misspelt_required_key_is_named_at_its_line_with_the_key_meant(tmp_path, capsys):
    """``ligth`` on line 6: that line first, with `light` suggested; the missing key after it.
    Catches the first pydantic error shown alone (``F:3: ...light: required key is missing (and 1
    more)``: the wrong line, the cause hidden)."""
    assert errors(tmp_path, capsys, TYPO, "list") == [
        "shadowbench: F:6: scenes.bunny.ligth: unknown key; did you mean `light`?",
        "shadowbench: F:3: scenes.bunny.light: required key is missing"]


def test_every_error_of_a_file_is_listed_with_its_line(tmp_path, capsys):
    """Four errors on three lines, the unknown keys first (one of an object of a union of
    shapes: `translate` suggested from the sphere's keys). Catches "(and N more)" in place of
    the others, and a suggestion drawn from the wrong model (none for `tranlate`)."""
    assert errors(tmp_path, capsys, THREE, "list") == [
        "shadowbench: F:8: scenes.one.objects.0.colour: unknown key",
        "shadowbench: F:9: scenes.one.objects.1.tranlate: unknown key; did you mean `translate`?",
        "shadowbench: F:4: scenes.one.camera.yfov: must be in [0.01, 180), got 260.0",
        "shadowbench: F:9: scenes.one.objects.1.radius: Input should be greater than 0"]


def test_an_experiment_key_misspelt(tmp_path, capsys):
    """``frame:`` in an experiment: `frames` suggested, at its line. Catches the suggestion
    taken only from the scene schema."""
    path = tmp_path / "exp.yaml"
    path.write_text("scenes: [box_plane]\ntechniques: {sm: {}}\nframe: 3\n")
    code = main(["plan", str(path)])
    err = capsys.readouterr().err
    assert code == 2
    assert err == f"shadowbench: {path}:3: frame: unknown key; did you mean `frames`?\n"
