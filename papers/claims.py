"""Every paper's claims: which experiment gives which claims, :func:`evaluate` over a papers
root and :func:`write` to its ``papers.json``.

Each paper is one module here (``pcf``, ``mdsm``, ``silhouette``, ``sv``, ``gmnpr``) whose
claim functions take the :class:`~papers.common.Runs` of one experiment's run directory
``ROOT/<experiment>`` (see ``experiments/papers/``); a paper whose directory is missing
contributes no measured claims. Thresholds that decide a verdict are module constants next to
the claim that uses them.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from harness import results

from . import gmnpr, mdsm, pcf, silhouette, sv
from .common import Claim, Runs

SCHEMA_VERSION = 1
CLAIMS_FILE = "papers.json"

# experiment directory -> its claims
EXPERIMENTS = {"pcf": pcf.claims, "mdsm": mdsm.table_claims, "mdsm_crossover": mdsm.crossover_claims,
               "silhouette": silhouette.claims, "sv": sv.table2_claims, "sv_camera": sv.camera_claims,
               "gmnpr": gmnpr.figure8_claims}


def evaluate(root: str | Path) -> list[Claim]:
    """Every claim the run directories under ``root`` (and the analytic formulas) support."""
    root = Path(root)
    claims = []
    for name, make in EXPERIMENTS.items():
        if (root / name / results.RESULTS_FILE).is_file():
            claims += make(Runs(root, name))
    return claims + gmnpr.analytic_claims()


def write(root: str | Path, claims: list[Claim], renderer: str = "") -> Path:
    root = Path(root)
    doc = {"schema": SCHEMA_VERSION, "renderer": renderer,
           "claims": [asdict(c) for c in claims]}
    path = root / CLAIMS_FILE
    tmp = root / f".{CLAIMS_FILE}.tmp"
    tmp.write_text(json.dumps(doc, indent=1, allow_nan=False, default=_jsonable))
    tmp.replace(path)
    return path


def _jsonable(value):
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    raise TypeError(f"not JSON: {type(value).__name__}")
