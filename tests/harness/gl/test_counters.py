"""Work counters (GL_ARB_pipeline_statistics_query) and the cost model built on them."""

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from harness import cli
from harness.analysis import cost_model
from harness.gl import measure

TRIVIAL_FRAGMENT = "out vec4 colour;\nvoid main() { colour = vec4(1.0); }\n"


def expected_fullscreen_fragments(width: int, height: int, renderer: str) -> int:
    """Fragment-shader invocations of one full-screen triangle at width x height (multiples
    of 4), counted by hand. A GPU runs the shader once per pixel. llvmpipe counts 16 per 4x4
    block a triangle touches, and its clipper cuts the full-screen triangle into two triangles
    along the viewport's diagonal, so the blocks that diagonal crosses count twice: a
    segment across an a x b grid of cells crosses a + b - gcd(a, b) of them."""
    if "llvmpipe" not in renderer:
        return width * height
    a, b = width // 4, height // 4
    return 16 * (a * b + a + b - math.gcd(a, b))


@pytest.mark.parametrize("size", [(64, 48), (60, 60), (128, 64)])
def test_fullscreen_triangle_counts(size, gl_context, tmp_path):
    """One full-screen triangle: 3 vertex invocations, 1 primitive into clipping, W*H samples
    passed, and the hand-counted fragment invocations.

    Catches: a counter read from the wrong query (GL_CLIPPING_OUTPUT_PRIMITIVES gives 3
    primitives here: the clipper's output, not its input)."""
    from OpenGL import GL

    from harness.gl.framebuffer import Framebuffer
    from harness.gl.geometry import FullscreenTriangle
    from harness.gl.shaders import HARNESS_GLSL, Program

    assert measure.pipeline_statistics_missing() == ""
    width, height = size
    (tmp_path / "white.frag.glsl").write_text(TRIVIAL_FRAGMENT)
    program = Program(HARNESS_GLSL / "fullscreen.vert.glsl", tmp_path / "white.frag.glsl")
    target = Framebuffer(width, height, (GL.GL_R32F,), depth=False)
    triangle = FullscreenTriangle()
    meter = measure.PassMeter(counters=True)
    try:
        meter.new_frame(measuring=True)
        with meter.measure("fullscreen"):
            target.bind()
            GL.glDisable(GL.GL_DEPTH_TEST)
            program.use()
            triangle.draw()
        (stats,) = meter.passes()
    finally:
        for resource in (meter, triangle, target, program):
            resource.release()
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
    assert stats.fragments == width * height
    assert stats.vertex_invocations == 3
    assert stats.primitives == 1
    assert stats.fragment_invocations == expected_fullscreen_fragments(width, height,
                                                                        gl_context.renderer)


def test_a_run_counts_its_scene_triangles(scene_at, evaluate, gl_context):
    """sm on box_plane: the shadow-map pass draws the scene's T triangles indexed (one vertex
    invocation per shared vertex, 12 on box_plane, T primitives), the shading pass one
    full-screen triangle, the light fit none (CPU work); the row's counters are the sums of its
    passes, for one frame whatever the number of frames.

    Catches: counters summed over every measured frame (x frames), or the row taking one
    pass's counts."""
    scene = scene_at("box_plane", 64, 48)
    row = evaluate(scene, "sm", {"res": 256}, frames=3, warmup=1).row
    triangles = len(scene.triangles)
    light_fit, shadow_map, shading = row["passes"]  # cost: dynamic, the default
    assert (shadow_map["vertex_invocations"], shadow_map["primitives"]) == (
        len(scene.indexed[0]), triangles)
    assert (light_fit["vertex_invocations"], light_fit["primitives"]) == (0, 0)
    assert (shading["vertex_invocations"], shading["primitives"]) == (3, 1)
    assert shading["fragment_invocations"] == expected_fullscreen_fragments(
        64, 48, gl_context.renderer)
    for counter in measure.COUNTERS:
        assert row[counter] == light_fit[counter] + shadow_map[counter] + shading[counter]
    # the map pass shades every fragment of the scene's triangles seen from the light
    assert shadow_map["fragment_invocations"] >= shadow_map["fragments"] > 0


def _run(tmp_path, scene_file, *extra, techniques="sm,pcf,sv"):
    out = tmp_path / "out"
    code = cli.main(["run", "--scene-file", str(scene_file), "--techniques", techniques,
                     "--set", "pcf.k=4", "--frames", "2", "--warmup", "0", "--out", str(out),
                     "--quiet", *extra])
    with (out / "results.csv").open() as f:
        return code, out, list(csv.DictReader(f))


def test_gpu_estimate_is_the_model_on_the_stored_counters(tmp_path, small_scene_file,
                                                          gl_context):
    """Recomputed from results.csv alone with the RTX 4090's published rates (whitepaper:
    443.5 Gpixel/s, 1290.2 Gtexel/s, 1008 GB/s; 82.6 TFLOPS at 64 FLOP a vertex or compute
    invocation, 40 a node or triangle test), a compute traversal (ptsv's volumes against view
    samples) included: its node and sample tests are stored as traversal_nodes and
    triangle_tests, which the model prices.

    Catches: an estimate from other counts than the stored ones (e.g. fetches per pixel not
    multiplied by the covered pixels, or counters of another frame), coefficients that are not
    the cited figures, and a traversal's tests stored under names the model does not read
    (ptsv's first ``node_tests`` and ``sample_tests``: no traversal_nodes)."""
    code, _, rows = _run(tmp_path, small_scene_file("box_plane", "sphere_plane"),
                         techniques="sm,pcf,sv,ptsv")
    assert code == 0 and len(rows) == 8
    for r in rows:
        work = {k: float(r[k] or 0) for k in ("compute_invocations", "traversal_nodes",
                                              "triangle_tests")}
        seconds = ((float(r["vertex_invocations"]) + work["compute_invocations"]) * 64 / 82.6e12
                   + float(r["fragment_invocations"]) / 443.5e9
                   + float(r["fetches_per_px"]) * float(r["covered_px"]) / 1290.2e9
                   + float(r["mem_bytes"]) / 1008e9
                   + (work["traversal_nodes"] + work["triangle_tests"]) * 40 / 82.6e12)
        assert float(r["gpu_estimate_ms"]) == pytest.approx(seconds * 1e3, rel=1e-9), r
        assert float(r["covered_px"]) > 0 and float(r["vertex_invocations"]) > 0
        if r["technique"] == "ptsv":
            assert work["traversal_nodes"] > 0 and work["triangle_tests"] > 0, r


def test_without_pipeline_statistics_columns_are_empty_and_the_manifest_says_why(
        tmp_path, small_scene_file, monkeypatch, gl_context):
    """A driver without the extension is not an error: exit 0, every run ok, the counter
    columns and the estimate empty, and the manifest names the reason.

    Catches: counters asked of a driver that lacks them (a GL error, or failed runs), and
    zeros written where nothing was counted."""
    reason = "the GL driver (test) lacks GL_ARB_pipeline_statistics_query"
    monkeypatch.setattr(measure, "pipeline_statistics_missing", lambda: reason)
    code, out, rows = _run(tmp_path, small_scene_file("box_plane"))
    assert code == 0 and {r["status"] for r in rows} == {"ok"}
    for r in rows:
        assert all(r[c] == "" for c in (*measure.COUNTERS, "gpu_estimate_ms")), r
        assert r["time_ms"] != "" and r["frags_shadow"] != ""
        assert all(set(p) == {"name", "ms", "ms_ci_low", "ms_ci_high", "fragments"}
                   for p in json.loads(r["passes"]))
    manifest = json.loads((Path(out) / "manifest.json").read_text())
    assert manifest["gl"]["pipeline_statistics"] == {"available": False, "why": reason}


TRUTH = cost_model.Coefficients("truth", "test", 0.2, 1e-5, 2e-6, 4e-6, 1e-8, 3e-6, 5e-7, 7e-7)


def counted_rows(rng, runs: int) -> list[dict]:
    """``runs`` results rows with random work counters and no time; the odd ones traced rays
    (traversal nodes and triangle tests), the even ones have no such columns."""
    rows = []
    for i in range(runs):
        row = {"status": "ok", "scene": "s", "width": 8, "height": 8, "technique": "t",
               "params": "{}", "passes": json.dumps([{}] * int(rng.integers(1, 5))),
               "vertex_invocations": int(rng.integers(3, 10**5)),
               "fragment_invocations": int(rng.integers(10**3, 10**7)),
               "fetches_per_px": float(rng.integers(1, 17)),
               "covered_px": int(rng.integers(10**3, 10**6)),
               "mem_bytes": int(rng.integers(0, 2**26)),
               "compute_invocations": int(rng.integers(0, 10**6))}
        if i % 2:
            row.update(traversal_nodes=int(rng.integers(10**4, 10**7)),
                       triangle_tests=int(rng.integers(10**3, 10**6)))
        rows.append(row)
    return rows


def test_fit_recovers_known_coefficients():
    """Rows made from known coefficients: the fit returns them and reports R^2 = 1 and no
    error; the stored llvmpipe coefficients are non-negative. Half the rows traced rays
    (traversal nodes and triangle tests), the others have no such columns (no work: 0).

    Catches: features in another order than the coefficients, scaling not undone, a row
    without traversal counts taken as unusable."""
    rows = counted_rows(np.random.default_rng(0), 40)
    for row in rows:
        row["time_ms"] = cost_model.estimate_ms(row, TRUTH)
    fitted = cost_model.fit(rows)
    assert np.allclose(fitted.vector(), TRUTH.vector(), rtol=1e-6)
    quality = cost_model.fit_quality(rows, fitted)
    assert quality["r2"] == pytest.approx(1.0) and quality["worst_relative_error"] < 1e-6
    assert (cost_model.LLVMPIPE.vector() >= 0).all()


def test_fit_report_on_a_folder_without_runs_exits_2(tmp_path, capsys):
    """Catches: a traceback (or a fit of nothing) for a folder with no usable runs."""
    assert cost_model.main([str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "0 ok runs with work counters" in err


def test_fit_terms_prices_new_work_without_moving_the_rest():
    """Rows made from known coefficients, half with traversal work: fitting only per_node_ms
    and per_test_ms from a base that has the other terms right (and those two at 0) recovers
    the two, leaves the others as they were, and uses only the rows with traversal work.
    Catches: the fixed terms' time not taken off first (the two absorb it), rows without the
    work in the fit, an unknown term accepted."""
    base = dataclasses.replace(TRUTH, per_node_ms=0.0, per_test_ms=0.0)
    rows = counted_rows(np.random.default_rng(1), 30)
    for i, row in enumerate(rows):  # the rows without traversal work off the base model
        row["time_ms"] = cost_model.estimate_ms(row, TRUTH) * (1.5 if i % 2 == 0 else 1.0)
    fitted = cost_model.fit_terms(rows, base, ("per_node_ms", "per_test_ms"))
    assert np.allclose(fitted.vector(), TRUTH.vector(), rtol=1e-6)
    assert "over 15 runs" in fitted.source
    with pytest.raises(ValueError, match="terms must be some of"):
        cost_model.fit_terms(rows, base, ("per_nodes_ms",))
