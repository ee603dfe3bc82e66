"""What every paper's claims share: the :class:`Claim` record, :class:`Runs` (the current rows
and arrays of one experiment's run directory) and small helpers that judge numbers.

A claim names its paper and figure or table, what the paper reports, what we measured, the
tolerance it is judged by and the verdict; one that does not agree says why. Claims may carry
the run arrays to show side by side (``images``: paths relative to the papers root), a small
table and a plot (analytic curves or measured series); the report renders any of these without
knowing the papers, so a claim holds data only, never HTML.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness import analysis, results
from harness.truth import metrics

# V strictly between these is penumbra: a filtered, soft edge pixel
PENUMBRA = (0.02, 0.98)
# pixels either side of a reference shadow edge within which penumbra counts as edge width:
# wide enough for the widest filtered edge of the paper experiments (a 4 x 4 kernel of 2-pixel
# texels, 8 px), narrow against their lit and shadowed regions, where penumbra is acne or leaks
EDGE_WIDTH_BAND = 8
# edge width is the edge's only where the runs do not self-shadow: acne
# (harness.truth.metrics.acne_pct) beyond that band below this share of the pixels
ACNE_MAX_PCT = 0.1


@dataclass
class Claim:
    paper: str
    where: str  # "Figure 7", "Table 1", "Equations 5-6"
    claim: str  # the statement under test, in a line
    reported: str  # what the paper reports
    measured: str  # what we measure
    tolerance: str  # how the two are compared
    agrees: bool
    why_not: str = ""  # required when the claim does not agree; cleared when it does
    experiment: str = ""  # run directory under the papers root, "" for analytic claims
    images: list[dict] = field(default_factory=list)  # {label, array, reference}
    table: dict | None = None  # {columns: [...], rows: [[...], ...]}
    plot: dict | None = None  # {x_title, y_title, log_y, series: [{name, x, y, dash?}]}

    def __post_init__(self):
        self.agrees = bool(self.agrees)
        if self.agrees:  # why_not is the reason given should the claim fail
            self.why_not = ""
        elif not self.why_not:
            raise ValueError(f"{self.paper} {self.where}: a claim that does not agree says why")


class MissingRun(LookupError):
    pass


def _same(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
    return a == b


class Runs:
    """The current successful rows of one experiment's run directory."""

    def __init__(self, root: Path, name: str):
        self.root, self.name = Path(root), name
        # only ok runs of the techniques' code as it is now: a directory reused across versions
        # keeps older rows, which must not stand in for (or beside) the current ones
        self.rows = analysis.current(results.load(self.root / name))

    def all(self, technique: str, scene: str | None = None, **params):
        rows = self.rows[self.rows["technique"] == technique]
        if scene is not None:
            rows = rows[rows["scene"] == scene]
        keep = [all(_same(p.get(k), v) for k, v in params.items()) for p in rows["params"]]
        return rows[keep]

    def one(self, technique: str, scene: str | None = None, width: int | None = None, **params):
        rows = self.all(technique, scene, **params)
        if width is not None:
            rows = rows[rows["width"] == width]
        if len(rows) != 1:
            raise MissingRun(f"{self.name}: {len(rows)} ok runs of {technique} {scene or ''} "
                             f"{width or ''} {params}, expected one")
        return rows.iloc[0]

    def arrays(self, row) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """V, its coverage, the reference V and its coverage of one row."""
        with np.load(self.root / self.name / row["array"]) as z:
            v, covered = z["visibility"], z["covered"]
        with np.load(self._reference(row)) as z:
            return v, covered, z["visibility"], z["covered"]

    def _reference(self, row) -> Path:
        return self.root / self.name / row["reference_array"]

    def image(self, row, label: str) -> dict:
        return {"label": label, "array": f"{self.name}/{row['array']}",
                "reference": str(self._reference(row).relative_to(self.root))}


def edge_width_px(runs: Runs, row, *, width: int = EDGE_WIDTH_BAND) -> int:
    """A soft edge's width as an area: the penumbra pixels (fractional V) within ``width``
    pixels of a reference shadow edge. Along the same edges (one scene and view) it grows with
    the edge's mean width; penumbra away from every edge (acne, leaks) does not count."""
    v, covered, ref, ref_covered = runs.arrays(row)
    band = metrics.edge_band(ref, mask=covered & ref_covered, width=width)
    return int((band & (v > PENUMBRA[0]) & (v < PENUMBRA[1])).sum())


def acne_beyond_edges_pct(runs: Runs, row, *, width: int = EDGE_WIDTH_BAND) -> float:
    """``harness.truth.metrics.acne_pct`` of a row with the band of :func:`edge_width_px`: a soft edge
    wider than the row's own 2-pixel band is penumbra there, not acne."""
    v, covered, ref, ref_covered = runs.arrays(row)
    return metrics.acne_pct(v, ref, mask=covered & ref_covered, width=width)


def timed_note(rows) -> str:
    """What a timing claim adds to its measurement when some of its runs were timed while other
    processes used the CPU (the rows' ``noisy``): their times are inflated."""
    noisy = sum(r.get("noisy", 0) == 1 for r in rows)  # 0, 1, or empty in older results
    return (f"; {noisy} of {len(rows)} timed runs noisy (a busy machine: times inflated)"
            if noisy else "")


def signed_pct(value: float, base: float) -> str:
    return f"{100 * (value - base) / base:+.3g} %"


def increasing(values, strict=True) -> bool:
    pairs = list(zip(values, values[1:]))
    return all(b > a for a, b in pairs) if strict else all(b >= a for a, b in pairs)


def g(x) -> str:
    """A number as the claims print it: three significant digits."""
    return f"{x:.3g}"


def within_factor(measured: float, reported: float, factor: float) -> bool:
    return reported / factor <= measured <= reported * factor
