"""A linear cost model over the work a run counted: time that carries to another renderer.

    estimate_ms = per_pass_ms     * passes              (measured passes per frame)
                + per_vertex_ms   * vertex_invocations  (pipeline statistics)
                + per_fragment_ms * fragment_invocations
                + per_fetch_ms    * fetches             (fetches_per_px * covered_px)
                + per_byte_ms     * bytes               (mem_bytes: the maps, written each frame)
                + per_compute_ms  * compute_invocations (the GPU reductions, e.g. the warps')
                + per_node_ms     * traversal_nodes     (hierarchy nodes a frame's traversal tested)
                + per_test_ms     * triangle_tests      (its triangle tests at the leaves)

Vertex invocations count every vertex a measured pass shades: the scene's shared vertices in
each map pass (indexed meshes), and the volume vertices a shadow-volume pass extrudes. Compute
invocations count the reductions' work (one invocation per 16-pixel column of each dispatch)
and the work of techniques built on compute shaders (one invocation per triangle set up, per
ray, per queued work item).
A technique that traverses a hierarchy counts its work in an untimed repeat, per frame:
``traversal_nodes``, the nodes tested (a ray's BVH nodes entered, or the nodes of view samples
a triangle's shadow volume was tested against; an irregular z-buffer's samples linked into its
lists, one atomic step each), and ``triangle_tests``, the tests of one triangle at the leaves
(against a ray, or its volume or shadow frustum against a view sample: the same four planes);
a row without them did none (0). A compute invocation tests several nodes in a loop, so the invocation term
alone does not price them.

All inputs are per frame and stored in each results row, so any estimate can be recomputed
from results.csv. Two coefficient sets:

``RTX_4090``: NVIDIA GeForce RTX 4090 at its published peak rates, so the estimate is the
throughput bound (a lower bound: no latency, no pass overhead, every unit busy). Figures from
NVIDIA, "NVIDIA Ada GPU Architecture" whitepaper (2023), appendix table "GeForce RTX 4090":
176 ROPs and 512 texture units at a 2520 MHz boost clock give a peak pixel fill rate of
443.5 Gpixel/s (per fragment) and a peak texel rate of 1290.2 Gtexel/s (per fetch); 384-bit
GDDR6X at 21 Gbps gives 1008 GB/s (per byte). The whitepaper gives no vertex rate: per vertex
assumes 64 FP32 operations (two 4x4 matrix-vector products, what our vertex shaders do) at the
whitepaper's 82.6 TFLOPS (1.29e12 vertices/s); per compute invocation likewise (a reduction's
pixel: up to three 4x4 matrix-vector products and a shared-memory step); per node tested 40
FP32 operations (a ray's two slab tests: 12 multiply-subtracts and 12 min/max each, and their
compares; a shadow volume's test of a box takes about 100, each of its four planes' nearest and
farthest corner and its bounds across the light, so there the bound is looser still), per
triangle test 40 (Woop et al.'s shear and three 2D edge functions: about 30, with the
distance; a view sample against a volume's four planes, about 30). A compute traversal on such
a GPU is bound by its memory latency more than by these rates (and RT cores do the same work
in fixed function), so for traversals the bound is the loosest. Pass overhead is not modelled
(0).

``LLVMPIPE``: fitted here by non-negative least squares (:func:`fit`) to llvmpipe's measured
``time_ms``, so the model's fit is checkable: ``python -m harness.analysis.cost_model DIR`` prints R^2
and the worst relative error of these coefficients over DIR's runs, and of a fit to DIR itself.
Note that llvmpipe counts fragment invocations per 4x4 block (harness.gl.measure), so the
per-fragment coefficients of the two sets apply to slightly different counts.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass, replace

import numpy as np

FEATURES = ("passes", "vertices", "fragments", "fetches", "bytes", "computes", "nodes", "tests")


@dataclass(frozen=True)
class Coefficients:
    """Milliseconds per unit of each feature; ``name`` says which renderer, ``source`` how."""

    name: str
    source: str
    per_pass_ms: float
    per_vertex_ms: float
    per_fragment_ms: float
    per_fetch_ms: float
    per_byte_ms: float
    per_compute_ms: float
    per_node_ms: float = 0.0
    per_test_ms: float = 0.0

    def vector(self) -> np.ndarray:
        return np.array([self.per_pass_ms, self.per_vertex_ms, self.per_fragment_ms,
                         self.per_fetch_ms, self.per_byte_ms, self.per_compute_ms,
                         self.per_node_ms, self.per_test_ms])


RTX_4090 = Coefficients(
    name="NVIDIA GeForce RTX 4090 (peak rates)",
    source="NVIDIA Ada GPU Architecture whitepaper: 443.5 Gpixel/s, 1290.2 Gtexel/s, 1008 GB/s, "
           "82.6 TFLOPS at 64 FLOP per vertex",
    per_pass_ms=0.0,
    per_vertex_ms=1e3 / (82.6e12 / 64),
    per_fragment_ms=1e3 / 443.5e9,
    per_fetch_ms=1e3 / 1290.2e9,
    per_byte_ms=1e3 / 1008e9,
    per_compute_ms=1e3 / (82.6e12 / 64),
    per_node_ms=1e3 / (82.6e12 / 40),
    per_test_ms=1e3 / (82.6e12 / 40),
)

# Fitted under cost: dynamic (every frame charged its maps, fits, reductions and traversals)
# by fit() to the two quiet runs of 2026-12-03 on this project's machine (2 cores, nothing else
# running): `make bench` (541 ok runs: every technique along its curve on the ten shipped
# scenes) and `make scale` (648 ok runs: the four scale families at 10^3 to 10^6 triangles), the
# ptsv rows' node and sample tests as traversal_nodes and triangle_tests; 1189 runs. R^2 0.895
# over scale's runs, 0.867 over bench's (median relative error 27% and 34%); per technique, the
# median relative error from 11% (pcf) and 12% (ptsv, R^2 0.98) to 55% (rt). The previous
# coefficients (374 bench runs on shared cores, before rt and ptsv) gave R^2 -4.3 and -7.2 on
# the same runs: their per-compute term priced every compute invocation as a reduction's
# pixel, and a traversal's invocations do very different work. That term now fits to 0 (the
# reductions' cost is carried by the per-pass term), and the two traversal terms to 14.8 and
# 12.7 ns a node or triangle test, close to the about 20 ns per node-volume test measured for
# ptsv's traversal alone. Refit with ``python -m harness.analysis.cost_model DIR`` (both fits printed).
LLVMPIPE = Coefficients(
    name="llvmpipe (Mesa 22.3.6, LLVM 15.0.6, 256 bits), 2 cores",
    source="fit() over make bench and make scale, 1189 runs, quiet, cost: dynamic",
    per_pass_ms=2.393,
    per_vertex_ms=1.272e-4,
    per_fragment_ms=2.546e-6,
    per_fetch_ms=5.030e-6,
    per_byte_ms=1.527e-7,
    per_compute_ms=0.0,
    per_node_ms=1.479e-5,
    per_test_ms=1.274e-5,
)

GPU = RTX_4090  # what results rows store as gpu_estimate_ms


def _number(value) -> float | None:
    if value is None or value == "":
        return None
    x = float(value)
    return None if math.isnan(x) else x


def features(row: dict) -> np.ndarray | None:
    """The model's inputs (in ``FEATURES`` order) from a results row, typed or as CSV
    strings; None where a count is missing (no pipeline statistics, a failed run)."""
    passes = row.get("passes")
    if isinstance(passes, str):
        passes = json.loads(passes) if passes else None
    values = [_number(row.get(k)) for k in ("vertex_invocations", "fragment_invocations",
                                            "fetches_per_px", "covered_px", "mem_bytes",
                                            "compute_invocations")]
    if passes is None or any(v is None for v in values):
        return None
    vertices, fragments, fetches_per_px, covered_px, mem_bytes, computes = values
    traversal = [_number(row.get(k)) or 0.0 for k in ("traversal_nodes", "triangle_tests")]
    return np.array([len(passes), vertices, fragments, fetches_per_px * covered_px, mem_bytes,
                     computes, *traversal])


def estimate_ms(row: dict, coefficients: Coefficients = GPU) -> float | None:
    """The model's time for one row's counted work; None where a count is missing."""
    x = features(row)
    return None if x is None else float(x @ coefficients.vector())


def fit(rows: list[dict], name: str = "fitted") -> Coefficients:
    """Non-negative least squares of ``time_ms`` on the features of ``rows`` (each column
    scaled to its largest value first, so the fit does not depend on units)."""
    x, t = _design(rows)
    if len(t) < len(FEATURES):
        raise ValueError(f"need at least {len(FEATURES)} runs with counters to fit, got {len(t)}")
    from scipy.optimize import nnls

    scale = np.where(x.max(axis=0) > 0, x.max(axis=0), 1.0)
    c, _ = nnls(x / scale, t)
    return Coefficients(name, f"nnls over {len(t)} runs", *(c / scale))


def fit_terms(rows: list[dict], base: Coefficients, terms: tuple[str, ...],
              name: str = "fitted") -> Coefficients:
    """``base`` with only ``terms`` (``per_node_ms``, ...) fitted: non-negative least squares
    of what ``base``'s other terms leave of ``time_ms``, over the rows that have work in
    those terms (a technique that joined after ``base`` was fitted: its own terms priced
    without moving the rest)."""
    fields = [f for f in asdict(base) if f.startswith("per_")]
    unknown = sorted(set(terms) - set(fields))
    if unknown or not terms:
        raise ValueError(f"terms must be some of {', '.join(fields)}; got {', '.join(terms)}")
    x, t = _design(rows)
    picked = np.array([f in terms for f in fields])
    has_work = (x[:, picked] > 0).any(axis=1)
    x, t = x[has_work], t[has_work]
    if len(t) < picked.sum():
        raise ValueError(f"need at least {picked.sum()} runs with work in {', '.join(terms)} "
                         f"to fit them, got {len(t)}")
    from scipy.optimize import nnls

    rest = t - x[:, ~picked] @ base.vector()[~picked]
    scale = np.where(x[:, picked].max(axis=0) > 0, x[:, picked].max(axis=0), 1.0)
    c, _ = nnls(x[:, picked] / scale, rest)
    values = dict(zip((f for f, p in zip(fields, picked) if p), c / scale))
    return replace(base, name=name, source=f"{base.source}; {', '.join(terms)} by nnls over "
                                            f"{len(t)} runs", **values)


def fit_quality(rows: list[dict], coefficients: Coefficients) -> dict:
    """R^2 of the model's times against ``time_ms``, the worst and median relative errors and
    the run with the worst error."""
    x, t = _design(rows)
    kept = [r for r in rows if _usable(r)]
    predicted = x @ coefficients.vector()
    residual = ((t - predicted) ** 2).sum()
    total = ((t - t.mean()) ** 2).sum()
    relative = np.abs(predicted - t) / t
    worst = int(np.argmax(relative))
    w = kept[worst]
    return {"runs": len(t), "r2": float(1 - residual / total) if total > 0 else float("nan"),
            "worst_relative_error": float(relative[worst]),
            "median_relative_error": float(np.median(relative)),
            "worst_run": f"{w['scene']} {w['width']}x{w['height']} {w['technique']} "
                         f"{w['params']}: {float(w['time_ms']):.3g} ms measured, "
                         f"{predicted[worst]:.3g} ms modelled"}


def _usable(row: dict) -> bool:
    return (row.get("status") == "ok" and features(row) is not None
            and (_number(row.get("time_ms")) or 0) > 0)


def _design(rows: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    kept = [r for r in rows if _usable(r)]
    x = np.array([features(r) for r in kept]).reshape(len(kept), len(FEATURES))
    return x, np.array([float(r["time_ms"]) for r in kept])


def main(argv: list[str] | None = None) -> int:
    from ..results import read_rows

    p = argparse.ArgumentParser(prog="python -m harness.analysis.cost_model",
                                description="fit of the llvmpipe cost model over a results folder")
    p.add_argument("dir", help="a run directory (its results.csv)")
    p.add_argument("--terms", help="fit only these terms (per_node_ms,per_test_ms), the "
                                   "others kept at the stored llvmpipe values")
    args = p.parse_args(argv)
    rows = read_rows(args.dir)
    usable = [r for r in rows if _usable(r)]
    if len(usable) < len(FEATURES):
        print(f"python -m harness.analysis.cost_model: {args.dir}: {len(usable)} ok runs with work "
              f"counters, need at least {len(FEATURES)}", file=sys.stderr)
        return 2
    noisy = sum(r.get("noisy") == "1" for r in usable)
    print(f"{args.dir}: {len(usable)} ok runs with work counters ({noisy} noisy)")
    try:
        refit = (fit_terms(usable, LLVMPIPE, tuple(args.terms.split(",")),
                           name=f"{args.terms} fitted to {args.dir}") if args.terms
                 else fit(usable, name=f"fitted to {args.dir}"))
    except ValueError as e:
        print(f"python -m harness.analysis.cost_model: {args.dir}: {e}", file=sys.stderr)
        return 2
    for coefficients in (LLVMPIPE, refit):
        quality = fit_quality(usable, coefficients)
        print(f"\n{coefficients.name} ({coefficients.source}):")
        for key, value in asdict(coefficients).items():
            if key.startswith("per_"):
                print(f"  {key:16s} {value:.4g}")
        print(f"  R^2 {quality['r2']:.3f}, worst relative error "
              f"{quality['worst_relative_error']:.0%} ({quality['worst_run']}), median "
              f"{quality['median_relative_error']:.0%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
