"""Paper reproductions: claims decided from results (synthetic and one real experiment), the
papers.json schema, and the Papers page with its links."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from harness import cli, registry, report, results
from papers import claims, common, gmnpr, mdsm, silhouette

ROOT = Path(__file__).resolve().parent.parent
REQUIRED = {"paper": str, "where": str, "claim": str, "reported": str, "measured": str,
            "tolerance": str, "agrees": bool, "why_not": str, "experiment": str, "images": list}


def _row(technique, scene="s", width=256, params=None, **values):
    params = params or {}
    run_id = f"{technique}-{scene}-{width}-{json.dumps(params, sort_keys=True)}"
    return {"run_id": run_id, "schema": 1, "scene": scene, "technique": technique,
            "params": params, "width": width, "height": width, "status": "ok",
            "code_version": registry.get(technique).code_version(),
            "array": f"arrays/{scene}/{width}x{width}/{technique}-x.npz", **values}


def _write(root: Path, name: str, rows: list[dict]) -> common.Runs:
    (root / name).mkdir(parents=True)
    results.write_rows(root / name, rows)
    return common.Runs(root, name)


@pytest.mark.parametrize("mdsm_times, agrees", [
    # f / 512^2 of each view: 0.25, 1.0, 1.5, 4.0; PCF(16, 1) at 10, 40, 60, 160 ms
    ([8, 50, 50, 100], True),    # cheaper from f = 1.5 x res^2: within a factor 2 of 1.28
    ([8, 30, 50, 100], False),  # cheaper from 0.25: too early (factor 5)
    ([20, 50, 70, 170], False),  # never cheaper: a reversed ordering
])
def test_mdsm_crossover_decided_from_times(tmp_path, mdsm_times, agrees):
    widths, fractions, pcf_times = [256, 512, 640, 1024], [0.25, 1.0, 1.5, 4.0], [10, 40, 60, 160]
    rows = []
    for w, frac, tp, tm in zip(widths, fractions, pcf_times, mdsm_times):
        rows.append(_row("pcf", width=w, params={"k": 16, "res": 512}, time_ms=tp))
        rows.append(_row("mdsm", width=w, params={"k": 9, "n": 2, "res": 512}, time_ms=tm,
                         shaded_px=frac * 512**2))
    (claim,) = mdsm.crossover_claims(_write(tmp_path, "mdsm_crossover", rows))
    assert claim.agrees is agrees
    assert bool(claim.why_not) is not agrees
    if mdsm_times[-1] > pcf_times[-1]:
        assert "reversed" in claim.why_not
    assert [s["name"] for s in claim.plot["series"]][:2] == ["PCF(16, 1)", "MDSM(9, 2)"]


def test_silhouette_table_claims_compare_with_the_paper(tmp_path):
    # O: crowd 10 (paper 154.2: off), castle 5 (paper 4.03: within 2x); P under 1/6 in both
    rows = []
    for scene, o, p, times in [("crowd", 10.0, 2.0, (5, 9, 8)), ("castle", 5.0, 7.0, (6, 4, 9))]:
        rows += [_row("sm", scene, time_ms=times[0], edge_mae=0.1),
                 _row("sv", scene, time_ms=times[1], overdraw=o, edge_mae=0.05),
                 _row("silhouette", scene, time_ms=times[2], sil_pct=p, edge_mae=0.07)]
    found = {(c.where, c.claim): c for c in silhouette.claims(_write(tmp_path, "silh", rows))}
    assert not found["Table 1", "shadow-volume overdraw O on crowd"].agrees
    assert found["Table 1", "shadow-volume overdraw O on castle"].agrees
    assert found["Table 1", "silhouette fraction P on castle"].agrees  # 7.0 vs 7.2
    assert not found["Table 1", "silhouette fraction P on crowd"].agrees  # 2.0 vs 13.3
    cheapest = next(c for (w, t), c in found.items() if t.startswith("shadow maps are"))
    assert not cheapest.agrees and "castle: sv cheapest" in cheapest.why_not
    quality = next(c for (w, t), c in found.items() if t.startswith("silhouette maps improve"))
    assert quality.agrees


def test_gmnpr_analytic_figures_hold():
    fig5, fig6 = gmnpr.analytic_claims()
    assert fig5.agrees and fig6.agrees
    # Figure 6 at theta = 90 degrees by hand: psi (z + varphi)^2 / z with lambda_1
    n, f, phi = 1.0, 100.0, math.pi / 6
    lam = (n + math.sqrt(f * n)) / (f - n)  # equation 4 at theta = 90 (t = 0)
    a = f - n
    F = [1 / (math.tan(phi) * a * lam * (lam + 1)) * (z + a * lam - n) ** 2 / z for z in (n, f)]
    assert F[0] == pytest.approx(F[1], rel=1e-12)
    gmnpr_90 = next(s for s in fig6.plot["series"] if s["name"] == "GMNPR theta=90")
    assert gmnpr_90["y"][0] == pytest.approx(F[0], rel=1e-9)


def test_a_disagreeing_claim_must_say_why():
    with pytest.raises(ValueError, match="says why"):
        common.Claim("p", "Table 1", "c", "r", "m", "t", agrees=False)


@pytest.fixture(scope="module")
def mdsm_run(tmp_path_factory):
    """The real MDSM experiment (32 runs at 256^2 with a 128 map), run once."""
    root = tmp_path_factory.mktemp("papers")
    status = cli.main(["run", str(ROOT / "experiments/papers/mdsm.yaml"),
                       "--out", str(root / "mdsm"), "--quiet"])
    assert status == 0
    return root


def test_real_mdsm_experiment_reproduces_table_1(mdsm_run):
    found = claims.evaluate(mdsm_run)
    table1 = next(c for c in found if c.paper == mdsm.PAPER and c.where == "Table 1")
    assert table1.agrees
    levels = {(int(r[0]), n + 1): int(cell.split()[0])
              for r in table1.table["rows"] for n, cell in enumerate(r[1:])}
    # never more outcomes than the paper's nk + 1, and exactly that for small kernels
    assert all(v <= k * n + 1 for (k, n), v in levels.items())
    assert levels[9, 2] == 19 and levels[16, 1] == 17 and levels[4, 3] == 13


def test_papers_json_schema_and_page(mdsm_run):
    found = claims.evaluate(mdsm_run)
    path = claims.write(mdsm_run, found, renderer="test")
    doc = json.loads(path.read_text())
    assert doc["schema"] == claims.SCHEMA_VERSION and len(doc["claims"]) == len(found)
    for c in doc["claims"]:
        for key, kind in REQUIRED.items():
            assert isinstance(c[key], kind), key
        assert bool(c["why_not"]) is not c["agrees"]
        for image in c["images"]:
            assert (mdsm_run / image["array"]).is_file()
            assert (mdsm_run / image["reference"]).is_file()
    # only MDSM ran, plus the analytic GMNPR figures
    assert {c["paper"] for c in doc["claims"]} == {mdsm.PAPER, gmnpr.PAPER}

    report.build_report(mdsm_run / "mdsm")
    index = (mdsm_run / "mdsm" / "index.html").read_text()
    assert '<a href="../papers.html">Papers</a>' in index
    page = report.build_papers_page(mdsm_run).read_text()
    assert page.count('<tr class="') == len(found)
    assert 'href="mdsm/index.html"' in page
    for i, c in enumerate(found):
        assert f'id="claim-{i}"' in page
    sources = re.findall(r'<img src="([^"]+)"', page)
    assert sources and all((mdsm_run / s).is_file() for s in sources)
    # the Figure 6 images: the reference and the four runs side by side, each with a crop
    fig6 = next(i for i, c in enumerate(found) if c.where == "Figure 6")
    assert sum(s.startswith(f"images/papers/claim-{fig6}/") for s in sources) == 10
    first = np.asarray(Image.open(mdsm_run / f"images/papers/claim-{fig6}/1.png"))
    assert first.shape[:2] == (256, 256)


def test_rows_of_older_code_are_left_out(tmp_path):
    current = _row("sm", params={"res": 512}, time_ms=1.0)
    older = {**_row("sm", params={"res": 1024}, time_ms=2.0), "code_version": "0" * 12}
    runs = _write(tmp_path, "x", [current, older])
    assert list(runs.rows["time_ms"]) == [1.0]
