"""The Papers page: ``ROOT/papers.html`` from ``ROOT/papers.json``, written by whatever evaluates
paper claims (this module knows no paper):

``{"schema": 1, "renderer": str, "claims": [{paper, where, claim, reported, measured, tolerance,
agrees, why_not, experiment, images: [{label, array, reference}], table: {columns, rows},
plot: {x_title, y_title, log_x, log_y, series: [{name, x, y, dash}]}}]}``; paths relative to ROOT.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

from . import images as im
from . import plots
from .render import render, write_page
from .stored import Folder

PAPERS_JSON = "papers.json"
PAPERS_HTML = "papers.html"


def papers_link(out_dir: Path) -> str | None:
    """Relative link to the Papers page of a run directory (or of the directory holding it)."""
    if (out_dir / PAPERS_JSON).is_file():
        return PAPERS_HTML
    if (out_dir.parent / PAPERS_JSON).is_file():
        return f"../{PAPERS_HTML}"
    return None


def claim_images(folder: Folder, images: list[dict]) -> dict | None:
    """The claim's runs side by side: the reference and each run's V, and beneath them the same
    enlarged edge crop (chosen on the first run's reference)."""
    if not images:
        return None
    z = folder.arrays(images[0]["reference"], "visibility", "covered", what="claim reference")
    if z is None:
        return None
    window = im.edge_crop(z["visibility"], z["covered"])
    cells = [("reference", im.visibility(z["visibility"], z["covered"]))]
    for image in images:
        run = folder.arrays(image["array"], "visibility", "covered", what=image["label"])
        if run is not None:
            cells.append((image["label"], im.visibility(run["visibility"], run["covered"])))
    return {"cells": [{"label": label, "full": im.data_uri(im.shrink_mean(v), im.VISIBILITY),
                       "crop": im.data_uri(im.crop(v, window), im.VISIBILITY) if window else None}
                      for label, v in cells],
            "window": list(window) if window else None}


def build_papers_page(root: str | Path) -> Path:
    """Write ``root/papers.html`` from ``root/papers.json``: a table of every claim (reported,
    measured, tolerance, agrees, why not), then each claim with its table, plot and images."""
    folder = Folder(root)
    doc = json.loads((folder.root / PAPERS_JSON).read_text())
    claims = []
    for claim in doc["claims"]:
        claims.append({**claim,
                       "chart": plots.series_chart(claim["plot"]) if claim.get("plot") else None,
                       "pictures": claim_images(folder, claim.get("images") or [])})
    page = render("papers.html.j2", claims=claims, renderer=doc.get("renderer") or "?",
                  experiments=sorted({c["experiment"] for c in claims if c.get("experiment")}),
                  notes=folder.notes,
                  built=dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"))
    return write_page(folder.root / PAPERS_HTML, page)
