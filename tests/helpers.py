"""Helpers shared by test modules (test modules never import each other): a valid small
scene, the command line run in-process or as a subprocess, small real runs and results
folders, moving scenes, and one-frame renders."""

from __future__ import annotations

import copy
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import yaml

from harness import cli, config, results
from harness.technique import registry
from harness.cli import main as shadowbench
from harness.scene import build_scene
from harness.technique import Frame, reset_gl_state

GOOD = {
    "resolution": [32, 32],
    "camera": {"position": [0, -6, 4], "target": [0, 0, 0], "up": [0, 0, 1], "yfov": 60,
               "near": 0.1, "far": 100},
    "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
    "effects": ["shadow"],
    "objects": [{"shape": "plane", "size": [10, 10]},
                {"shape": "box", "size": [1, 1, 1], "translate": [0, 0, 1.5]}],
}


ROOT = Path(__file__).resolve().parent.parent  # the repository
DATA = Path(__file__).resolve().parent / "data"  # the tests' own files
SCENE_FILE = ROOT / "scenes.yaml"  # the shipped scenes


PY = sys.executable


HOSTILE_SCENE = "x\" onerror=\"document.title='PWNED'\""


HOSTILE_TECHNIQUE = "<img src=x onerror=alert(1)>"

SMALL = [[64, 64], [96, 96]]

# Two scenes: one shadow-only (directional light) and one shaded (spot light, so flip exists).
SCENES = ["box_plane", "sphere_plane"]

SCALE_SIZES = (1e3, 1e4, 1e5, 1e6)

# sm and sv times at equal error per size: sv / sm = 0.25, 0.5, 2, 4 (crossing at 10^4.5)
SCALE_TIMES = {"sm": (1, 2, 4, 8), "sv": (0.25, 1, 8, 32)}

def view_direction(scene_config):
    cam = scene_config.camera
    d = np.subtract(cam.target, cam.position)
    return d / np.linalg.norm(d)


def scene_with(**changes) -> dict:
    """GOOD with ``a__b__0=value`` changes (keys joined by double underscores)."""
    scene = copy.deepcopy(GOOD)
    for path, value in changes.items():
        *parents, last = [int(k) if k.isdigit() else k for k in path.split("__")]
        node = scene
        for key in parents:
            node = node[key]
        node[last] = value
    return scene


def write_scenes(folder: Path, scenes: dict) -> Path:
    path = folder / "scenes.yaml"
    path.write_text(yaml.safe_dump({"scenes": scenes}, sort_keys=False))
    return path


def files_under(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*") if p.is_file()}


def run_cli(args, capsys) -> tuple[int, list[str]]:
    code = cli.main([str(a) for a in args])
    return code, capsys.readouterr().err.strip().splitlines()


def sweep(scene_file, out, *more):
    return ["run", "--scene-file", scene_file, "--techniques", "sm", "--out", out, "--quiet",
            *more]


def assert_one_line(code, err, expected_code, *needles):
    assert code == expected_code, err
    assert len(err) == 1, err
    assert "Traceback" not in err[0]
    for needle in needles:
        assert needle in err[0], err


def assert_bad_setting_exits_2(tmp_path, capsys, technique: str, setting: str, message: str):
    """An experiment running ``technique`` with ``setting`` (YAML flow mapping) on box_plane
    exits 2 with one line naming the file and holding ``message``, and writes nothing."""
    experiment = tmp_path / "bad.yaml"
    experiment.write_text(f"scenes: [box_plane]\ntechniques:\n  {technique}: "
                          f"[{{set: {setting}}}]\n")
    out = tmp_path / "out"
    code, err = run_cli(["run", experiment, "--out", out], capsys)
    assert_one_line(code, err, 2, str(experiment), message)
    assert not out.exists()


def subprocess_env(**extra) -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT), **extra}


def can_mount_tmpfs() -> bool:
    try:
        return subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs none /mnt"],
                              capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.SubprocessError):
        return False


needs_tmpfs = pytest.mark.skipif(not can_mount_tmpfs(), reason="no mount namespace here "
                                 "(unshare -rm) for a small or read-only file system")


def small_run(tmp_path, *techniques, frames=1):
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({
        "techniques": {t: None for t in techniques or ("sm",)}, "frames": frames, "warmup": 0,
        "reference": {"samples": 1}}))
    args = ["run", str(experiment), "--scene-file", str(scene_file), "--out",
            str(tmp_path / "out"), "--quiet"]
    return args


def result_rows(out):
    """The rows of ``out``/results.csv as dicts of strings, in file order."""
    with (Path(out) / "results.csv").open() as f:
        return list(csv.DictReader(f))


def rows_by_run_id(out):
    return {r["run_id"]: r for r in result_rows(out)}


def cli_subprocess(args, timeout=60) -> tuple[int, list[str]]:
    proc = subprocess.run([sys.executable, "-m", "harness.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT,
                          env=subprocess_env())
    return proc.returncode, proc.stderr.strip().splitlines()


def moving(shipped_scenes, name, size, **motion_keys):
    """A shipped scene at ``size`` (width, height) with ``motion``; without keys, still."""
    scene = shipped_scenes[name].model_dump(mode="json")
    scene["resolution"] = list(size)
    if motion_keys:
        scene["motion"] = motion_keys
    return build_scene(name, config.Scene(**scene))


def render_visibility(technique, frame):
    frame.meter.new_frame(True)
    try:
        return technique.render(frame).visibility
    finally:
        reset_gl_state()


@contextmanager
def rendered(scene, **params):
    """The silhouette technique run once on ``scene`` (one cost: dynamic frame, its update and
    render measured), kept alive for inspection."""
    from harness.technique import reset_gl_state
    from techniques.silhouette.silhouette import SilhouetteMap

    frame = Frame(scene)
    technique = SilhouetteMap(SilhouetteMap.Params(**params))
    try:
        technique.prepare(frame)
        frame.meter.new_frame(measuring=True)
        technique.update(frame)
        output = technique.render(frame)
        yield frame, technique, output
    finally:
        technique.release()
        frame.release()
        reset_gl_state()


def light_at(scene_config, theta_deg, *, behind=True, beta_deg=30.0):
    """A light at ``theta_deg`` to the view direction, shining down, ``beta_deg`` off the
    vertical plane; ``behind``: it travels with the view (from behind the viewer)."""
    d = view_direction(scene_config)
    down = np.array([0.0, 0.0, -1.0]) - (-d[2]) * d
    down /= np.linalg.norm(down)
    side = np.cross(d, down)
    t, b = math.radians(theta_deg), math.radians(beta_deg)
    return ((1 if behind else -1) * math.cos(t) * d
            + math.sin(t) * (math.cos(b) * down + math.sin(b) * side))


def variant(shipped_scenes, name, width, **update):
    base = shipped_scenes[name]
    if "direction" in update:
        update["light"] = config.DirectionalLight(type="directional",
                                                  direction=list(update.pop("direction")))
    return build_scene(name, base.model_copy(update=update)).with_resolution(width, width)


def make_run_dir(out: Path) -> Path:
    """A small real run directory: an sm and pcf parameter grid, then every registered technique
    at its defaults, on two scenes at two resolutions, plus one failed row of a technique this
    install does not know (as results copied from elsewhere would have)."""
    common = {"scenes": SCENES, "resolutions": SMALL, "frames": 1, "warmup": 0,
              "reference": {"samples": 4}}
    grid = {**common, "techniques": {"sm": {"product": {"res": [256, 1024]}},
                                     "pcf": {"product": {"k": [4, 16]}}}}
    every = {**common, "techniques": "all"}
    for name, experiment in (("grid", grid), ("every", every)):
        path = out.parent / f"{out.name}-{name}.yaml"
        path.write_text(json.dumps(experiment))
        code = shadowbench(["run", str(path), "--scene-file", str(ROOT / "scenes.yaml"),
                            "--out", str(out), "--quiet"])
        assert code in (0, 1)
    rows = results.read_rows(out)
    rows.append({**rows[0], "run_id": "0" * 16, "technique": "broken_example",
                 "params": json.dumps({"res": 64}), "status": "error",
                 "error": "RuntimeError: shader failed to link", "time_ms": "", "mae": "",
                 "edge_mae": "", "wrong_pct": "", "array": ""})
    results.write_rows(out, rows)
    return out


def hostile_folder(folder: Path, make_results) -> Path:
    """A scene named to break out of an attribute, a failed run whose error is markup, and a
    parameter value that is a script."""
    make_results(folder, [{"params": {"res": 512}},
                          {"params": {"res": 1024}, "shift": 1},
                          {"params": {"res": 2048}, "status": "error",
                           "error": "<img src=x onerror=\"document.title='PWNED2'\">"},
                          {"params": {"res": 4096, "bias": "</script><script>alert(1)</script>"}}],
                 scene=HOSTILE_SCENE)
    return folder


def scale_folder(folder: Path, make_results) -> Path:
    """A results folder written by hand: family arch at 10^3..10^6 triangles with sm and sv at
    SCALE_TIMES (edge_mae 0.05, edge_floor 0.04: within 1.5 x floor) and sv's volume pass
    drawing 10 x triangles fragments; two ordinary scenes, box (2,500 triangles) and old (no
    count, run before it was recorded)."""

    runs = []
    for i, triangles in enumerate(SCALE_SIZES):
        for technique, times in SCALE_TIMES.items():
            passes = [{"name": "volumes", "ms": times[i] / 2, "fragments": 10 * triangles},
                      {"name": "visibility", "ms": times[i] / 2, "fragments": 1000}]
            runs.append({"scene": f"arch@{triangles:g}", "family": "arch",
                         "triangles": int(triangles), "technique": technique,
                         "code_version": registry.get(technique).code_version(),
                         "time_ms": times[i], "edge_mae": 0.05, "edge_floor": 0.04,
                         "frags_shadow": 10 * triangles + 1000, "passes": json.dumps(passes)})
    for scene, triangles in (("box", 2500), ("old", None)):
        runs += [{"scene": scene, "triangles": triangles, "time_ms": 1.0, "edge_mae": 0.05,
                  "edge_floor": 0.04}]
    make_results(folder, runs)
    rows = results.read_rows(folder)
    sv_defaults = json.dumps(registry.get("sv").Params().model_dump(mode="json"), sort_keys=True)
    for row in rows:  # make_results writes sm's parameters on every row
        if row["technique"] == "sv":
            row["params"] = sv_defaults
    results.write_rows(folder, rows)
    return folder


def one_frame_of(technique, frame):
    """A callable rendering one unmeasured frame of a prepared technique, to the GPU's end."""
    from OpenGL import GL  # after gl_context picked the platform

    def one_frame():
        frame.meter.new_frame(measuring=False)
        output = technique.render(frame)
        GL.glFinish()  # the frame is done when the GPU is, not when the calls return
        return output

    return one_frame


def canonical_triangles(triangles: np.ndarray) -> np.ndarray:
    """Triangles (T, 3, 3) in a canonical order, each turned to start at its smallest vertex
    (the same triangle, the same winding, whichever corner a fan starts at): (T, 9), to
    compare two loaders' triangles."""
    triangles = np.asarray(triangles, np.float64).round(6) + 0.0
    _, ids = np.unique(triangles.reshape(-1, 3), axis=0, return_inverse=True)
    first = np.argmin(ids.reshape(-1, 3), axis=1)
    turned = triangles[np.arange(len(triangles))[:, None], (first[:, None] + np.arange(3)) % 3]
    rows = turned.reshape(-1, 9)
    return rows[np.lexsort(rows.T[::-1])]


def cut_out(scene) -> bool:
    """A scene whose casters are alpha-tested (issue 48): an object's ``alpha`` key, or the
    ``cards`` family with its cut-outs. sv, ptsv and silhouette build their shadows from whole
    triangles and decline it by default; they are compared with the others on opaque scenes."""
    return any(obj.alpha is not None for obj in scene.objects) or (
        scene.family is not None and scene.family.kind == "cards" and scene.family.cutouts)


# The corpus's two largest meshes under their spot lights (the plates, 6 x 10^4 triangles, and
# robosuite's torso, 1.7 x 10^5): the per-scene exactness checks of sv, rt, ptsv and izb run
# these meshes under their suns only (real_plates, real_torso). Their spot variants took 30 s of
# the suite there, sv's volumes alone 4 s a render at 64 x 64; the spot path is checked on the
# corpus's other spot scenes (10^3 to 10^4 triangles) and the shipped and hard-case spots.
# test_sv_cull.py checks that these are the spot scenes above its LARGE_SCENE.
LARGE_SPOTS = frozenset({"real_plates_spot", "real_torso_spot"})


def real_corpus(scene) -> bool:
    """A scene built from a mesh file shipped inside an installed package (issue 32's corpus,
    10^4 to 10^5 triangles of real exporters' geometry)."""
    return any(getattr(obj, "package", None) for obj in scene.objects)


CHROMIUM = os.environ.get("SHADOWBENCH_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("SHADOWBENCH_CHROMEDRIVER", "/usr/bin/chromedriver")
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update",
                  "--disable-sync"]


def chromium(profile: Path, width: int = 1400, height: int = 1000):
    """Debian's headless Chromium driven by selenium, its window ``width`` x ``height``, the
    browser's console kept; a test fails (never skips) where it is not installed."""
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not shutil.which(p)]
    if missing:
        pytest.fail(f"{', '.join(missing)} not found: install Debian's chromium and "
                    "chromium-driver (make setup does), or set SHADOWBENCH_CHROMIUM and "
                    "SHADOWBENCH_CHROMEDRIVER")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in CHROMIUM_FLAGS + [f"--user-data-dir={profile}", f"--window-size={width},{height}"]:
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


BROWSER_WAIT_S = 60  # a chart page on 2 busy cores draws within seconds; a minute is a hang


def wait_for(driver, script: str, what: str):
    """The first truthy value of ``script`` in the browser, polled every 0.1 s; the test fails
    naming ``what`` after BROWSER_WAIT_S."""
    deadline = time.monotonic() + BROWSER_WAIT_S
    while time.monotonic() < deadline:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.1)
    pytest.fail(f"timed out after {BROWSER_WAIT_S} s waiting for {what}")


def render_once(technique, frame):
    """One measured frame of ``technique`` on ``frame`` (prepare, update, render), then the
    technique released and GL state reset; returns its ShadowOutput."""
    technique.prepare(frame)
    technique.update(frame)
    frame.meter.new_frame(True)
    output = technique.render(frame)
    technique.release()
    reset_gl_state()
    return output


# A checker-cut card over a ground plane under a directional light at 45 degrees: the card
# (CARD_SIZE square, its plane z = CARD_HEIGHT, centred at x = CARD_HEIGHT) casts its shadow
# around the origin, where the camera looks straight down; the card itself is outside the
# view (the camera sees ground only). CARD_POINT_LIGHT: a point light on the same diagonal,
# whose card shadow also falls around the origin (1.25 times the card's size).
CARD_HEIGHT, CARD_SIZE = 2.5, 2.0
CARD_LIGHT = np.array([-1.0, 0.0, -1.0]) / math.sqrt(2.0)
CARD_POINT_LIGHT = np.array([12.5, 0.0, 12.5])
CARD_GAP = 1e-3  # between copies of the card stacked along z
CARD_CAMERA = {"position": [0, 0, 6], "target": [0, 0, 0], "up": [0, 1, 0], "yfov": 40,
               "near": 0.1, "far": 100}
# straight down over the card's centre: the card fills the middle of the view, the ground
# around it and through its holes
CARD_OVER_CAMERA = {**CARD_CAMERA, "position": [CARD_HEIGHT, 0, 6], "target": [CARD_HEIGHT, 0, 0]}


def checker(texels: int, cells: int) -> np.ndarray:
    """A (texels, texels) uint8 checker of ``cells`` x ``cells`` squares, 255 and 0, the
    top-left one 255."""
    index = np.arange(texels) * cells // texels
    return np.where((index[:, None] + index[None, :]) % 2 == 0, 255, 0).astype(np.uint8)


def card_uv(points: np.ndarray) -> np.ndarray:
    """The card's texture coordinates (glTF: u right, v down the image) at points in its
    plane (..., 2 or 3): u along x, v down y, (0, 0) at its corner of least x and most y."""
    half = CARD_SIZE / 2
    return np.stack([(points[..., 0] - (CARD_HEIGHT - half)) / CARD_SIZE,
                     (half - points[..., 1]) / CARD_SIZE], axis=-1)


def alpha_card_scene(texture: np.ndarray, cutoff: float = 0.5, size: int = 256,
                     card_copies: int = 1, point_light: bool = False, motion: dict | None = None,
                     camera: dict = CARD_CAMERA, light: dict | None = None):
    """The card scene (above) at ``size`` x ``size``, the card cut out by ``texture``'s alpha
    at ``cutoff``, built in code (a BuiltScene: ground, then ``card_copies`` cards one above
    the other, CARD_GAP apart, sharing one cut-out), lit by CARD_LIGHT or CARD_POINT_LIGHT. Its key
    is the opaque scene's with the cut-out's digest (its own reference cache entry). ``motion``:
    the scene's motion (the cards are objects ``card0``, ``card1``, ...); ``camera``: another
    camera (CARD_OVER_CAMERA sees the card); ``light``: another light."""
    import dataclasses

    from harness.scene.alpha import AlphaMask

    card = {"shape": "plane", "size": [CARD_SIZE, CARD_SIZE]}
    scene = {"resolution": [size, size],
             "camera": camera,
             "light": light or ({"type": "point", "position": CARD_POINT_LIGHT.tolist()}
                                if point_light else
                                {"type": "directional", "direction": CARD_LIGHT.tolist()}),
             "effects": ["shadow"],
             "objects": [{"shape": "plane", "size": [10, 10]}] + [
                 {**card, "name": f"card{k}",
                  "translate": [CARD_HEIGHT, 0, CARD_HEIGHT + CARD_GAP * k]}
                 for k in range(card_copies)]}
    if motion:
        scene["motion"] = motion
    built = build_scene("alpha_card", config.Scene(**scene))
    mask = AlphaMask(texture, cutoff, "checker")
    parts = [built.parts[0]] + [
        dataclasses.replace(p, alpha=mask,
                            texcoords=card_uv(p.vertices[p.faces]).astype(np.float32))
        for p in built.parts[1:]]
    return dataclasses.replace(built, parts=parts, key=f"{built.key}-alpha-{mask.digest}")


def card_crossing(position: np.ndarray, point_light: bool = False, copy: int = 0):
    """Where each ground point's ray to the light crosses the plane of the card's ``copy``
    (float64 (..., 3)), and whether inside that card."""
    p = position.astype(np.float64)
    to_light = CARD_POINT_LIGHT - p if point_light else np.broadcast_to(-CARD_LIGHT, p.shape)
    s = (CARD_HEIGHT + CARD_GAP * copy - p[..., 2]) / to_light[..., 2]
    hit = p + s[..., None] * to_light
    return hit, np.all(np.abs(hit[..., :2] - [CARD_HEIGHT, 0.0]) <= CARD_SIZE / 2, axis=-1)


def card_visibility(position: np.ndarray, covered: np.ndarray, texture: np.ndarray,
                    cutoff: float, point_light: bool = False) -> np.ndarray:
    """The exact visibility of ground points (G-buffer positions (H, W, 3)) under the card,
    in float64 and independently of every technique: each point moved along its ray to the
    light to the card's plane, inside the card and its alpha by
    harness.scene.alpha.sample_alpha at or above the cutoff: 0, else 1. Uncovered pixels: 1."""
    from harness.scene.alpha import sample_alpha

    hit, inside = card_crossing(position, point_light)
    opaque = sample_alpha(texture, card_uv(hit)) >= cutoff
    return np.where(covered & inside & opaque, 0.0, 1.0)


# The technique contract run by hand, its GL objects counted before and after.
GL_NAME_RANGE = range(1, 2001)


def live_gl_names() -> dict[str, set[int]]:
    """The GL names alive now, by object kind (textures, framebuffers, programs, buffers, VAOs)."""
    from OpenGL import GL

    checks = {"texture": GL.glIsTexture, "framebuffer": GL.glIsFramebuffer,
              "program": GL.glIsProgram, "buffer": GL.glIsBuffer,
              "vertex array": GL.glIsVertexArray}
    return {kind: {i for i in GL_NAME_RANGE if is_live(i)} for kind, is_live in checks.items()}


def leaked(before: dict[str, set[int]], after: dict[str, set[int]]) -> dict[str, list[int]]:
    return {kind: sorted(after[kind] - before[kind]) for kind in after
            if after[kind] - before[kind]}


def run_contract(cls, scene, **params):
    """prepare, update, two measured renders, release, as the runner does (``params`` over the
    defaults); asserts that no GL object outlives the technique and the frame. Returns
    (outputs, passes), or (None, None) when the technique does not apply to the scene."""
    from harness.technique import NotApplicable

    before = live_gl_names()
    frame = Frame(scene)
    technique = cls(cls.Params(**params))
    outputs, passes = [], None
    try:
        try:
            technique.prepare(frame)
            technique.update(frame)
        except NotApplicable:
            outputs = None
        else:
            for _ in range(2):
                frame.meter.new_frame(True)
                outputs.append(technique.render(frame))
            passes = frame.meter.passes()
    finally:
        technique.release()  # also after NotApplicable: the runner releases every technique
        frame.release()
        reset_gl_state()
    gone = leaked(before, live_gl_names())
    assert not gone, f"{cls.name} leaks GL objects on {scene.name}: {gone}"
    return outputs, passes


def technique_visibility(frame: Frame, name: str, params: dict | None = None):
    """V and the row extras of technique ``name`` on ``frame`` (one update, one render)."""
    cls = registry.get(name)
    technique = cls(cls.Params(**(params or {})))
    try:
        technique.prepare(frame)
        technique.update(frame)
        frame.meter.new_frame(True)
        out = technique.render(frame)
        return out.visibility, out.extra
    finally:
        technique.release()
        reset_gl_state()


def on_a_boundary(v: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Whether each of ``pixels`` (a mask) has a 4-neighbour of the other value in ``v``."""
    padded = np.pad(v, 1, mode="edge")
    h, w = v.shape
    neighbours = [padded[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
                  for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1))]
    return pixels & np.any([n != v for n in neighbours], axis=0)
