"""Pagot, Comba, Oliveira, "Multiple-depth shadow maps" (MDSM): Table 1's outcomes, the
equivalences of Figures 6 and 7 (experiment ``mdsm``) and the cost crossover of equations 5-6
(experiment ``mdsm_crossover``)."""

from __future__ import annotations

import math

from .common import (
    ACNE_MAX_PCT,
    EDGE_WIDTH_BAND,
    Claim,
    Runs,
    acne_beyond_edges_pct,
    edge_width_px,
    g,
    signed_pct,
    timed_note,
)

PAPER = "Pagot, Comba, Oliveira (MDSM)"

TABLE = dict(res=128, q=16, select="sort")
OUTCOMES_SEEN = 0.95  # share of the nk + 1 outcomes a 256^2 view of one edge must show
EQUIVALENCE_REL = 0.2  # "comparable" / "very similar": edge width within 20 %
CROSSOVER = 1.28  # equations 5-6: MDSM(9, 2) fetches less than PCF(16, 1) once f > 1.28 x res^2


def table_claims(runs: Runs) -> list[Claim]:
    claims = []
    ks, ns = [1, 4, 9, 16], [1, 2, 3, 4]
    grid = {(k, n): int(runs.one("mdsm", "slant_edge", k=k, n=n, **TABLE)["levels"])
            for k in ks for n in ns}
    equal = sum(grid[kn] == kn[0] * kn[1] + 1 for kn in grid)
    close = all(OUTCOMES_SEEN * (k * n + 1) <= grid[k, n] <= k * n + 1 for k, n in grid)
    claims.append(Claim(
        PAPER, "Table 1", "PCF(k, n) on an n-SM produces nk + 1 outcomes",
        "nk + 1 outcomes, e.g. PCF(9, 2) 19 against PCF(16, 1) 17",
        f"distinct V values in the edge band of slant_edge equal nk + 1 for {equal} of "
        f"{len(grid)} (k, n); PCF(9, 2): {grid[9, 2]}, PCF(16, 1): {grid[16, 1]}",
        f"never more than nk + 1 and at least {100 * OUTCOMES_SEEN:g} % of it for every "
        "(k, n) in k 1, 4, 9, 16 x n 1..4 (a finite edge need not show every outcome)", close,
        why_not="some (k, n) exceed nk + 1 or fall well short of it on this edge",
        experiment=runs.name,
        table={"columns": ["k \\ n"] + [str(n) for n in ns],
               "rows": [[str(k)] + [f"{grid[k, n]} ({n * k + 1})" for n in ns] for k in ks]}))

    claims.append(equivalence(runs, "Figure 6", "slant_edge", [(9, 4, 3), (16, 9, 3)],
                              "PCF 3x3 ~ 3-SM PCF 2x2; PCF 4x4 ~ 3-SM PCF 3x3 (planar)"))
    claims.append(equivalence(runs, "Figure 7", "pins", [(16, 9, 2), (16, 9, 3)],
                              "PCF 4x4 ~ 2-SM and 3-SM with PCF 3x3 (curved receivers)"))
    return claims


def equivalence(runs: Runs, where: str, scene: str, triples, reported: str) -> Claim:
    """The n-SM's PCF(k, n) against the standard map's larger PCF(K, 1), for each (K, k, n) in
    ``triples``, in edge width: the figures compare how wide and smooth the shadow transitions
    look, not their accuracy against an exact shadow, which a wider edge lowers.

    The control is PCF(k, 1), the n-SM's own kernel without its extra depths: it must fall
    outside the tolerance, or a match would not show the extra depths at work (on pins PCF(9, 1)
    is within 12 % of PCF(16, 1) in edge_mae)."""
    width, acne, rows, images, lines, too_far, control_close = {}, {}, [], [], [], [], []
    below_control = []  # n-SMs narrower than their own kernel on the standard map

    def measure(k, n, label):
        if (k, n) not in width:
            row = runs.one("mdsm", scene, k=k, n=n, **TABLE)
            width[k, n], acne[label] = edge_width_px(runs, row), acne_beyond_edges_pct(runs, row)
            rows.append([label, width[k, n], g(acne[label]), g(float(row["edge_mae"])),
                         int(row["levels"])])
            images.append(runs.image(row, label))
        return width[k, n]

    for big, k, n in triples:
        w_standard = measure(big, 1, f"PCF({big},1)")
        w_nsm = measure(k, n, f"PCF({k},{n})")
        w_control = measure(k, 1, f"PCF({k},1), control")
        if abs(w_nsm - w_standard) > EQUIVALENCE_REL * w_standard:
            too_far.append((w_nsm > w_standard, f"PCF({k},{n}) {signed_pct(w_nsm, w_standard)} "
                                                f"against PCF({big},1)"))
        if w_nsm < w_control:
            below_control.append(f"PCF({k},{n}) {signed_pct(w_nsm, w_control)} against PCF({k},1)")
        close = f"PCF({k},1) {signed_pct(w_control, w_standard)} against PCF({big},1)"
        if abs(w_control - w_standard) <= EQUIVALENCE_REL * w_standard and close not in control_close:
            control_close.append(close)
        lines.append(f"PCF({big},1) {w_standard}, MDSM({k},{n}) {w_nsm} "
                     f"({signed_pct(w_nsm, w_standard)}), control PCF({k},1) {w_control} "
                     f"({signed_pct(w_control, w_standard)})")
    acned = [f"{label} {g(a)} %" for label, a in acne.items() if a >= ACNE_MAX_PCT]
    window = math.isqrt(TABLE["q"])
    reasons = []
    if acned:
        reasons.append(f"acne beyond the edge band in {', '.join(acned)}: these runs "
                       "self-shadow, so their edge width holds acne near the edges too")
    if any(wider for wider, _ in too_far):
        reasons.append("the n-SM's edge is wider than the larger kernel's ("
                       + ", ".join(t for wider, t in too_far if wider) + "): its extra depths "
                       f"are the middle samples of the sorted {window} x {window}-texel window "
                       f"(q = {TABLE['q']}), which sets how far they widen the edge, whatever "
                       "the kernel; the paper leaves the window open (\"a neighborhood\")")
    if any(not wider for wider, _ in too_far):
        reasons.append("the n-SM's edge is narrower than the larger kernel's ("
                       + ", ".join(t for wider, t in too_far if not wider) + ")"
                       + (f", even narrower than its kernel's alone ({', '.join(below_control)}): "
                          "its extra depths take shadow from the edge instead of adding it"
                          if below_control else ""))
    if control_close:
        reasons.append(f"the control is as close ({', '.join(control_close)}): the n-SM's "
                       "kernel alone gives the larger kernel's edge, so the match does not "
                       "show the extra depths at work")
    return Claim(
        PAPER, where, "an n-SM with a smaller PCF kernel gives the edge width of the standard "
        "map with the larger kernel (a match in edge width, not accuracy)", reported,
        f"edge width (penumbra pixels within {EDGE_WIDTH_BAND} px of a reference edge) on "
        f"{scene}: " + "; ".join(lines),
        f"the n-SM's edge width within {100 * EQUIVALENCE_REL:g} % of the standard map's, the "
        "control (the n-SM's kernel on the standard map) not within it, and acne beyond the "
        f"band < {ACNE_MAX_PCT:g} % in every run; edge_mae (accuracy) only shown",
        not too_far and not control_close and not acned, why_not="; ".join(reasons),
        experiment=runs.name, images=images,
        table={"columns": ["PCF(k, n)", "edge width (px)", f"acne beyond {EDGE_WIDTH_BAND} px (%)",
                           "edge_mae", "levels"], "rows": rows})


def _crossing(fs, diffs) -> tuple[float, float, float | None] | None:
    """Where ``diffs`` (MDSM minus PCF, by view, ``fs`` ascending) turns negative for good: the
    bracket (f before, f after] and the linear interpolation between them (None when MDSM is
    ahead at the first view already); None when it never does."""
    first = next((i for i in range(len(fs)) if all(d < 0 for d in diffs[i:])), None)
    if first is None:
        return None
    if first == 0:
        return 0.0, fs[0], None
    lo, hi, d_lo, d_hi = fs[first - 1], fs[first], diffs[first - 1], diffs[first]
    return lo, hi, lo + (hi - lo) * d_lo / (d_lo - d_hi)


def crossover_claims(runs: Runs) -> list[Claim]:
    """Equations 5-6 count texture fetches: PCF(16, 1) makes 16 per shaded fragment, MDSM(9, 2)
    q per map texel to select its second depths plus 9 per fragment. The claim is judged on the
    fetches each run counts (f: the view's shaded pixels, ``shaded_px``; MDSM's own
    ``select_fetches`` and ``shading_fetches``); the timings are shown beside them, not judged:
    on a software rasterizer a frame's time is not made of fetches alone."""
    mdsm = runs.all("mdsm", n=2, k=9).sort_values("shaded_px")
    res = int(mdsm["params"].iloc[0]["res"])
    views, timed = [], []  # views: (width, f / res^2, PCF fetches, MDSM fetches, PCF ms, MDSM ms)
    for _, m in mdsm.iterrows():
        p = runs.one("pcf", m["scene"], width=int(m["width"]), k=16)
        timed += [p, m]
        f = float(m["shaded_px"])
        views.append((int(m["width"]), f / res**2, f * float(p["fetches_per_px"]),
                      float(m["select_fetches"]) + float(m["shading_fetches"]),
                      float(p["time_ms"]), float(m["time_ms"])))
    fs = [v[1] for v in views]
    fetches = _crossing(fs, [v[3] - v[2] for v in views])
    times = _crossing(fs, [v[5] - v[4] for v in views])

    def says(crossing, fewer):
        if crossing is None:
            return f"MDSM never {fewer} up to f = {g(fs[-1])} x res^2"
        lo, hi, at = crossing
        if at is None:
            return f"MDSM {fewer} from the smallest view on (f = {g(hi)} x res^2)"
        return f"cross between f = {g(lo)} and {g(hi)} x res^2 (interpolated {g(at)})"

    agrees = fetches is not None and fetches[0] < CROSSOVER <= fetches[1]
    return [Claim(
        PAPER, "Equations 5-6", "MDSM(9, 2) needs fewer shadow-map fetches than PCF(16, 1) once "
        f"the shaded fragments f exceed {CROSSOVER} x res^2",
        f"crossover at f = {CROSSOVER} x {res}^2 (a 656^2 view, one fragment per pixel)",
        f"counted fetches {says(fetches, 'fewer')}; times on {runs.rows['renderer'].iloc[0]} "
        f"(not judged) {says(times, 'faster')}{timed_note(timed)}",
        f"the paper's {CROSSOVER} x res^2 between the last view where MDSM fetches more and the "
        "first from which it fetches less",
        agrees,
        why_not=(f"MDSM's counted fetches never fall below PCF's over the measured views "
                 f"(f up to {g(fs[-1])} x res^2)" if fetches is None else
                 f"the counted fetches cross between f = {g(fetches[0])} and {g(fetches[1])} x "
                 f"res^2, not at the paper's {CROSSOVER}: the runs do not count equation 4's "
                 "q x res^2 + k f against PCF's 16 f"),
        experiment=runs.name,
        table={"columns": ["view", "f / res^2", "PCF(16, 1) fetches", "MDSM(9, 2) fetches",
                           "PCF(16, 1) ms", "MDSM(9, 2) ms"],
               "rows": [[f"{w}^2", g(f), f"{g(fp / 1e6)} M", f"{g(fm / 1e6)} M", g(tp), g(tm)]
                        for w, f, fp, fm, tp, tm in views]},
        plot={"x_title": "f / res^2 (shaded fragments over map texels)",
              "y_title": "shadow-map fetches per frame (millions)", "log_y": False,
              "series": [{"name": "PCF(16, 1)", "x": fs, "y": [v[2] / 1e6 for v in views]},
                         {"name": "MDSM(9, 2)", "x": fs, "y": [v[3] / 1e6 for v in views]},
                         {"name": "equation 6 crossover", "x": [CROSSOVER] * 2,
                          "y": [0, max(max(v[2], v[3]) for v in views) / 1e6],
                          "dash": "dot"}]})]
