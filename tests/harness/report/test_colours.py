"""Dashboards agree (issue 47, friction 7): a technique has one colour in every dashboard,
whatever else ran; the built-ins are told apart; the theta plot joins no unrelated scenes."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from harness import results
from harness.report import build_report, plots
from harness.technique import colour, registry


def page_colours(index) -> dict[str, str]:
    """The colours the page's scene sections draw each technique in."""
    found = {}
    for m in re.findall(r'<script type="application/json" class="scene-data">(.*?)</script>',
                        index.read_text(), re.S):
        found.update(json.loads(m)["colours"])
    return found


def folder_of(tmp_path, make_results, name: str, techniques: list[str]):
    """A hand-written folder: sm's two runs, and one run of each other technique in
    ``techniques`` (sm's rows renamed, with that technique's code version)."""
    folder = make_results(tmp_path / name, [{"params": {"res": 512}},
                                            {"params": {"res": 1024}, "shift": 1}])
    rows = results.read_rows(folder)
    rows += [{**rows[0], "technique": t, "run_id": f"{i:015d}x",
              "code_version": registry.get(t).code_version()}
             for i, t in enumerate(techniques) if t != "sm"]
    results.write_rows(folder, rows)
    return folder


def test_a_technique_has_one_colour_in_every_dashboard(tmp_path, make_results):
    """sm beside pcf, and sm beside rt, sv and csm: one colour for sm (and each technique) in
    both pages. Catches the palette indexed by the folder's sorted techniques, which drew sm
    in another colour in each (tried: #2ca02c and #ff7f0e)."""
    one = page_colours(build_report(folder_of(tmp_path, make_results, "one", ["sm", "pcf"])))
    two = page_colours(build_report(folder_of(tmp_path, make_results, "two",
                                              ["csm", "rt", "sm", "sv"])))
    assert one["sm"] == two["sm"] == registry.colour("sm")
    assert {**one, **two} == {t: registry.colour(t) for t in ("sm", "pcf", "csm", "rt", "sv")}


def _lab(hex_colour: str) -> np.ndarray:
    from skimage.color import rgb2lab

    rgb = [int(hex_colour[i:i + 2], 16) / 255 for i in (1, 3, 5)]
    return rgb2lab(np.array([[rgb]]))[0, 0]


def test_the_built_ins_are_told_apart():
    """Every registered technique's colour is its own and far from every other's (CIE76
    distance at least 20 in Lab). Catches ten palette colours over eleven techniques (csm and
    sv were both #1f77b4 in a page of every technique, tried)."""
    names = list(registry.techniques())
    drawn = plots.colours(names)
    assert len(set(drawn.values())) == len(names), drawn
    labs = {t: _lab(c) for t, c in drawn.items()}
    close = [(a, b, round(float(np.linalg.norm(labs[a] - labs[b])), 1))
             for i, a in enumerate(names) for b in names[i + 1:]
             if np.linalg.norm(labs[a] - labs[b]) < 20]
    assert not close, close
    # the built-ins declare theirs, so none rests on how names happen to hash
    assert all(colour.declared_colour(registry.get(t)) for t in names)


def test_a_technique_declaring_none_gets_its_names_colour():
    """A name no installed technique has (a plugin's, not installed here) and a subclass of sm
    that declares none: each the colour of its name, the same every time, and the subclass not
    drawn as sm."""
    from techniques.sm.sm import ShadowMap

    class Biased(ShadowMap):
        name = "smbias"

    assert colour.declared_colour(Biased) is None
    assert registry.colour("a_plugin") == colour.name_colour("a_plugin") in colour.NAME_PALETTE
    assert plots.colours(["a_plugin", "sm"])["a_plugin"] == plots.colours(["a_plugin"])["a_plugin"]
    assert colour.name_colour("smbias") != registry.colour("sm")


@pytest.mark.parametrize("bad", ["red", "#12345", "#1234567", "url(x)", 0x1f77b4])
def test_a_colour_not_written_rrggbb_is_refused(bad):
    """It lands in a style attribute: anything but #rrggbb makes the entry point broken."""
    class Odd:
        colour = bad

    with pytest.raises(ValueError, match="#rrggbb"):
        colour.check_colour(Odd)


def test_the_colour_line_leaves_the_code_version_as_it_was():
    """Declaring or changing a colour renders nothing again: the line is left out of the
    hash; any other line is not."""
    body = b'class A:\n    name = "a"\n%s    x = 1\n'
    plain = body % b""
    for line in (b'    colour = "#1f77b4"\n', b"    colour = '#FF00aa'\n",
                 b'    colour: ClassVar[str] = "#000000"\n'):
        assert colour.strip_declaration(body % line) == plain
    assert colour.strip_declaration(body % b'    colour = pick("#1f77b4")\n') != plain


def theta_rows(views: list[tuple]) -> pd.DataFrame:
    """psm at 20, 40 and 60 degrees in scenes a, b, c with the given (triangles, covered_px)."""
    return pd.DataFrame({
        "scene": ["a", "b", "c"], "technique": ["psm"] * 3, "width": [64] * 3,
        "height": [64] * 3, "params": [{"res": 512}] * 3, "theta_deg": [40.0, 20.0, 60.0],
        "alias_mean": [2.0, 3.0, 1.5], "edge_mae": [0.2, 0.3, 0.1], "parts": [2] * 3,
        "triangles": [v[0] for v in views], "covered_px": [v[1] for v in views]})


def test_the_theta_plot_joins_no_unrelated_scenes():
    """Three unrelated scenes (other triangles, other coverage): three points, none joined.
    Catches the line through one technique's points of six unrelated make bench scenes
    (tried: one series of three points)."""
    spec = plots.theta(theta_rows([(12, 900), (500, 2000), (40_000, 3100)]), {"psm": "#111"})
    for facet in spec["facets"]:
        assert [len(s["points"]) for s in facet["series"]] == [1, 1, 1], facet
        assert {s["name"].split()[-1] for s in facet["series"]} == {"a", "b", "c"}


def test_the_theta_plot_joins_a_light_sweep_of_one_scene():
    """Scenes that differ in their light alone (theta_sweep's: same triangles, parts, image
    size and covered pixels): one line in angle order."""
    spec = plots.theta(theta_rows([(500, 2000)] * 3), {"psm": "#111"})
    alias = next(f for f in spec["facets"] if f["title"] == "alias_mean")
    [line] = alias["series"]
    assert [(p["x"], p["y"]) for p in line["points"]] == [(20.0, 3.0), (40.0, 2.0), (60.0, 1.5)]
    assert line["name"] == "psm 64x64 3 lights"
