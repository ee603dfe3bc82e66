"""Issue 48's table from a run of experiments/alpha.yaml (``make alpha``): per technique, on
``cards`` (each size) and ``alpha_fence``, wrong_pct, edge_mae / edge_floor (``edge_ratio``) and time_ms
with the cut-outs and with the same triangles opaque (the ``*_opaque`` twins), as Markdown.

    .venv/bin/python benchmarks/alpha_table.py results/alpha/results.csv
"""

from __future__ import annotations

import argparse

import pandas as pd

TWINS = {"cards": "cards_opaque", "alpha_fence": "alpha_fence_opaque"}


def setting(row) -> str:
    """The technique, and its backend where it is not the default."""
    return f"{row.technique} (embree)" if '"embree"' in str(row.params) else row.technique


def table(results: pd.DataFrame) -> str:
    results = results.copy()
    results["setting"] = results.apply(setting, axis=1)
    lines = []
    for scene in sorted(results.scene.unique()):
        name, _, size = scene.partition("@")
        if name not in TWINS:
            continue
        cut = results[results.scene == scene].set_index("setting")
        twin = TWINS[name] + (f"@{size}" if size else "")
        opaque = results[results.scene == twin].set_index("setting")
        lines += [f"**{scene}** (with cut-outs / opaque)", "",
                  "| technique | alpha | wrong_pct | edge_mae ÷ edge_floor | time_ms |",
                  "|---|---|---|---|---|"]
        for name in cut.index:
            a, o = cut.loc[name], opaque.loc[name]
            lines.append(f"| {name} | {a.alpha} | {a.wrong_pct:.2f} / {o.wrong_pct:.2f} | "
                         f"{a.edge_ratio:.2f} / {o.edge_ratio:.2f} | "
                         f"{a.time_ms:.1f} / {o.time_ms:.1f} |")
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", help="results.csv of a run of experiments/alpha.yaml")
    print(table(pd.read_csv(parser.parse_args().results)))


if __name__ == "__main__":
    main()
