"""Sen, Cammarano, Hanrahan 2003, "Shadow silhouette maps": Table 1's overdraw O, silhouette
fraction P and costs, and section 4's bandwidth break-even points (experiment ``silhouette``)."""

from __future__ import annotations

from .common import Claim, Runs, g, timed_note, within_factor

PAPER = "Sen, Cammarano, Hanrahan 2003 (silhouette maps)"

# Table 1: scene -> (overdraw O, silhouette fraction P in %, fps of SM, SV, silhouette map)
TABLE = {"crowd": (154.2, 13.3, (11.5, 9.2, 9.5)),
                    "jeep": (5.55, 12.6, (75, 72, 58)),
                    "castle": (4.03, 7.2, (97, 95, 80))}
FACTOR = 2.0  # O and P within a factor 2 of the paper's scene
O_BREAK_EVEN = 4 / 5.5  # section 4: shadow volumes use more bandwidth than maps when O > 4/5.5
P_BREAK_EVEN = 100 / 6  # silhouette maps use < 2x a map's bandwidth when P < 1/6


def claims(runs: Runs) -> list[Claim]:
    scenes = [s for s in TABLE if s in set(runs.rows["scene"])]
    o = {s: float(runs.one("sv", s)["overdraw"]) for s in scenes}
    p = {s: float(runs.one("silhouette", s)["sil_pct"]) for s in scenes}
    rows = {s: [runs.one(t, s) for t in ("sm", "sv", "silhouette")] for s in scenes}
    claims = []
    for s in scenes:
        paper_o, paper_p, _ = TABLE[s]
        claims.append(Claim(
            PAPER, "Table 1", f"shadow-volume overdraw O on {s}",
            f"O = {paper_o:g}", f"O = {g(o[s])}", f"within a factor {FACTOR:g}",
            within_factor(o[s], paper_o, FACTOR),
            why_not=("our scene is a stand-in built from the paper's description, not its model "
                     "and view; O depends on how many volumes the view looks along"),
            experiment=runs.name))
        claims.append(Claim(
            PAPER, "Table 1", f"silhouette fraction P on {s}",
            f"P = {paper_p:g} % (zoomed in on the shadow, so 'artificially high')",
            f"P = {g(p[s])} %", f"within a factor {FACTOR:g}",
            within_factor(p[s], paper_p, FACTOR),
            why_not=("the paper zoomed in on the shadows to measure P; our views show whole "
                     "scenes, so fewer pixels lie on silhouettes"),
            experiment=runs.name))
    claims.append(Claim(
        PAPER, "Section 4", "shadow volumes need more bandwidth than shadow maps: O > 4/5.5 "
        "in every scene", "O between 4 and 155 in the test scenes",
        ", ".join(f"{s} {g(o[s])}" for s in scenes), f"O > {g(O_BREAK_EVEN)} in every scene",
        all(v > O_BREAK_EVEN for v in o.values()), why_not="some scene has O below 4/5.5",
        experiment=runs.name))
    claims.append(Claim(
        PAPER, "Section 4", "silhouette maps use less than twice a shadow map's bandwidth: "
        "P < 1/6", "P < 16 % in every scene",
        ", ".join(f"{s} {g(p[s])} %" for s in scenes), f"P < {g(P_BREAK_EVEN)} % everywhere",
        all(v < P_BREAK_EVEN for v in p.values()), why_not="some scene has P above 1/6",
        experiment=runs.name))
    cheapest = {s: min(zip((float(r["time_ms"]) for r in rows[s]), ("sm", "sv", "silhouette")))[1]
                for s in scenes}
    claims.append(Claim(
        PAPER, "Table 1", "shadow maps are the cheapest of the three techniques",
        "; ".join(f"{s}: SM {f[0]}, SV {f[1]}, silhouette {f[2]} fps"
                  for s, (_, _, f) in TABLE.items() if s in scenes),
        "; ".join(f"{s}: SM {g(float(a['time_ms']))}, SV {g(float(b['time_ms']))}, silhouette "
                  f"{g(float(c['time_ms']))} ms" for s, (a, b, c) in rows.items())
        + timed_note([r for s in scenes for r in rows[s]]),
        "sm has the smallest time_ms in every scene (absolute times differ by machine)",
        all(c == "sm" for c in cheapest.values()),
        why_not="a reversed ordering that the machine does not explain: " + ", ".join(
            f"{s}: {c} cheapest" for s, c in cheapest.items() if c != "sm"),
        experiment=runs.name,
        images=[runs.image(r, f"{s}: {t}") for s in scenes[1:2]
                for t, r in zip(("sm", "sv", "silhouette"), rows[s])]))
    better = {s: (float(rows[s][2]["edge_mae"]), float(rows[s][0]["edge_mae"])) for s in scenes}
    claims.append(Claim(
        PAPER, "Section 4", "silhouette maps improve shadow quality substantially over "
        "shadow maps of the same resolution", "substantial improvement in every scene",
        "edge_mae silhouette vs sm: " + ", ".join(f"{s} {g(a)} vs {g(b)}"
                                                  for s, (a, b) in better.items()),
        "silhouette edge_mae below sm's in every scene",
        all(a < b for a, b in better.values()), why_not="some scene shows no improvement",
        experiment=runs.name))
    return claims
