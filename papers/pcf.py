"""Reeves, Salesin, Cook 1987, "Rendering antialiased shadows with depth maps" (PCF):
Figures 7-10 as one-parameter sweeps and Table 1's cost of shadows (experiment ``pcf``)."""

from __future__ import annotations

import numpy as np

from .common import Claim, Runs, g, increasing, within_factor

PAPER = "Reeves, Salesin, Cook 1987 (PCF)"

BASE = dict(res=512, k=16, res_factor=1.0, bias_min=0.042, bias_max=0.056)
COST_PCT = (40.0, 50.0)  # Table 1: "an image with shadows costs 40% to 50% more"
COST_FACTOR = 2.0

# V strictly between these counts as penumbra (a filtered, soft edge pixel)
PENUMBRA = (0.02, 0.98)
# a reference pixel at least this lit (at most this dark) is lit (shadowed) for acne and leaks
LIT, DARK = 0.99, 0.01


def _pct(mask: np.ndarray, within: np.ndarray) -> float:
    return 100.0 * float((mask & within).sum()) / max(int(within.sum()), 1)


def penumbra_pct(runs: Runs, row) -> float:
    """Percent of covered pixels whose V is fractional: the width of the soft edges."""
    v, cov, _, ref_cov = runs.arrays(row)
    return _pct((v > PENUMBRA[0]) & (v < PENUMBRA[1]), cov & ref_cov)


def acne_pct(runs: Runs, row) -> float:
    """Percent of pixels lit in the reference that the technique puts mostly in shadow."""
    v, cov, ref, ref_cov = runs.arrays(row)
    return _pct(v < 0.5, cov & ref_cov & (ref >= LIT))


def leak_pct(runs: Runs, row) -> float:
    """Percent of pixels shadowed in the reference that the technique lights mostly."""
    v, cov, ref, ref_cov = runs.arrays(row)
    return _pct(v > 0.5, cov & ref_cov & (ref <= DARK))



def claims(runs: Runs) -> list[Claim]:
    def sweep(name, values, **fixed):
        base = {k: v for k, v in BASE.items() if k not in fixed and k != name}
        base.update(fixed)
        return [runs.one("pcf", **{**base, name: value}) for value in values]

    claims = []
    ks = [1, 4, 16]
    rows = sweep("k", ks)
    levels = [int(r["levels"]) for r in rows]
    claims.append(Claim(
        PAPER, "Figure 7", "NumSamples k gives shadow intensities of log2 k bits: at most k + 1 "
        "levels, more samples for smoother edges",
        "edges quantised to k + 1 intensities; k = 1 noisy, 16 the normal choice",
        "levels in the edge band: " + ", ".join(f"k={k}: {n}" for k, n in zip(ks, levels)),
        "levels <= k + 1 for each k, and increasing with k",
        all(n <= k + 1 for k, n in zip(ks, levels)) and increasing(levels),
        why_not="the level count exceeds k + 1 or does not grow with k",
        experiment=runs.name, images=[runs.image(r, f"NumSamples {k}") for k, r in zip(ks, rows)]))

    factors = [1, 3, 8]
    rows = sweep("res_factor", factors)
    soft = [penumbra_pct(runs, r) for r in rows]
    claims.append(Claim(
        PAPER, "Figure 8", "a larger ResFactor gives softer (wider) shadow edges",
        "softer shadow edges as ResFactor grows from 1 to 3 to 8",
        "penumbra (0.02 < V < 0.98) " + ", ".join(f"ResFactor {f}: {g(p)} %"
                                                   for f, p in zip(factors, soft)),
        "penumbra share strictly increasing with ResFactor",
        increasing(soft), why_not="the penumbra does not widen with ResFactor",
        experiment=runs.name,
        images=[runs.image(r, f"ResFactor {f}") for f, r in zip(factors, rows)]))

    biases = [(0.0, 0.0), (0.028, 0.042), (0.042, 0.056)]
    rows = [runs.one("pcf", **{**BASE, "bias_min": lo, "bias_max": hi}) for lo, hi in biases]
    acne = [acne_pct(runs, r) for r in rows]
    leak = [leak_pct(runs, r) for r in rows]
    labels = ["(0, 0)", "(0.2, 0.3)", "(0.3, 0.4)"]
    claims.append(Claim(
        PAPER, "Figure 9", "increasing Bias removes incorrect self-shadowing (moire)",
        "Bias (0, 0) shows moire self-shadowing; (0.2, 0.3) and (0.3, 0.4) remove it",
        "acne (lit in the reference, V < 0.5) " + ", ".join(
            f"Bias {b} x 0.14: {g(a)} %" for b, a in zip(labels, acne)),
        "acne at (0, 0) > 1 % of lit pixels and at (0.3, 0.4) < 0.1 %, non-increasing",
        acne[0] > 1.0 and acne[2] < 0.1 and acne == sorted(acne, reverse=True),
        why_not="the bias sweep does not remove the self-shadowing as reported",
        experiment=runs.name,
        images=[runs.image(r, f"Bias {b} x 0.14") for b, r in zip(labels, rows)]))
    claims.append(Claim(
        PAPER, "Figure 9", "increasing Bias moves the shadow boundary away from its true position",
        "the boundary moves (light leaks into the shadow) as Bias grows",
        "leak (shadowed in the reference, V > 0.5) " + ", ".join(
            f"Bias {b}: {g(x)} %" for b, x in zip(labels, leak)),
        "leak non-decreasing with Bias and larger at (0.3, 0.4) than at (0, 0)",
        increasing(leak, strict=False) and leak[2] > leak[0],
        why_not="at these biases the boundary does not measurably move",
        experiment=runs.name))

    sizes = [256, 512, 1024]
    rows = sweep("res", sizes)
    edge = [float(r["edge_mae"]) for r in rows]
    claims.append(Claim(
        PAPER, "Figure 10", "a larger depth map gives sharper, less blurry and noisy shadows",
        "256^2 blurry and noisy, 512^2 and 1024^2 progressively sharper",
        "edge_mae " + ", ".join(f"{s}^2: {g(e)}" for s, e in zip(sizes, edge)),
        "edge_mae strictly decreasing with map resolution",
        increasing(edge[::-1]), why_not="edge error does not fall with map resolution",
        experiment=runs.name, images=[runs.image(r, f"map {s}^2") for s, r in zip(sizes, rows)]))

    base = runs.one("pcf", **BASE)
    cost = 100.0 * float(base["time_ms"]) / float(base["scene_ms"])
    mid = sum(COST_PCT) / 2
    claims.append(Claim(
        PAPER, "Table 1", "shadows cost 40-50 % more than the image without shadows",
        f"{COST_PCT[0]:g}-{COST_PCT[1]:g} % more on average",
        f"PCF(16), 512^2 map, 512^2 image: {g(float(base['time_ms']))} ms over a "
        f"{g(float(base['scene_ms']))} ms unshadowed pass = {g(cost)} %",
        f"within a factor {COST_FACTOR:g} of {mid:g} %",
        within_factor(cost, mid, COST_FACTOR),
        why_not=("the paper's unshadowed image is a full 1024-wide REYES render with 16 samples "
                 "per pixel, shading dominating its cost; ours is a G-buffer pass that writes "
                 "positions and normals only, so the same shadow work is a larger share of it"),
        experiment=runs.name))
    claims.append(Claim(
        PAPER, "Table 1", "shadows cost less than rendering the image again "
        "((1 + lights) x the unshadowed cost)",
        "increase well below 100 % for one light",
        f"{g(cost)} % for one light", "increase < 100 %", cost < 100.0,
        why_not=("our unshadowed pass is far cheaper than a shaded render (see above), and 16 "
                 "map fetches per pixel cost more than one G-buffer write"),
        experiment=runs.name))
    return claims
