"""Plugin docs that cannot go stale (issue 35): each technique's docstring table (Parameter,
Meaning, Default, Range) says what its ``Params`` say: the same parameters, defaults and
bounds. Checked for every registered technique and for the example plugin a new author copies.
"""

import re
import sys
import typing

import annotated_types as at
import pytest
from pydantic_core import PydanticUndefined

from harness.technique import registry
from helpers import ROOT



def table(doc: str) -> dict[str, dict[str, str]]:
    """The docstring's parameter table, an RST simple table whose header row starts with
    ``Parameter``: each ``name`` with its columns' text on the row's first line (Default,
    Range), columns cut where the ``=====`` rule's gaps are."""
    lines = doc.splitlines()
    header = next(i for i, line in enumerate(lines) if line.strip().startswith("Parameter")
                  and set(lines[i - 1].strip()) <= {"=", " "})
    rule = lines[header - 1]
    spans = [(m.start(), m.end()) for m in re.finditer(r"=+", rule)]
    names = [lines[header][a:b].strip() for a, b in spans]
    # the last column runs to the end of the line
    cut = [(a, spans[i + 1][0] if i + 1 < len(spans) else None) for i, (a, _) in enumerate(spans)]
    rows = {}
    for line in lines[header + 2:]:
        if set(line.strip()) <= {"="}:
            break
        first = line[cut[0][0]:cut[0][1]].strip()
        if first.startswith("``"):
            rows[first.strip("`")] = {n: line[a:b].strip() for n, (a, b) in zip(names, cut)}
    return rows


def shown(value) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def same_default(text: str, value) -> bool:
    try:
        return float(text) == float(value) and not isinstance(value, (bool, str))
    except (TypeError, ValueError):
        return text == shown(value)


def bounds(field) -> dict[str, float]:
    out = {}
    for meta in field.metadata:
        for kind in (at.Ge, at.Gt, at.Le, at.Lt):
            if isinstance(meta, kind):
                out[kind.__name__.lower()] = getattr(meta, kind.__name__.lower())
    return out


def range_problems(text: str, field) -> list[str]:
    """What the Range cell says that the field does not: ``A .. B`` (ge A where the field has a
    lower bound, le B), ``(A, B]``, ``>= A`` with a number, and a list of words (a Literal's or
    a bool's values, in any order). Other forms (``>= bias_min``) are not checked."""
    b = bounds(field)
    problems = []
    if m := re.fullmatch(r"(?:.*, )?([-\d.e]+) \.\. ([-\d.e]+)", text):
        low, high = float(m[1]), float(m[2])
        if ("ge" in b and b["ge"] != low) or ("gt" in b and b["gt"] >= low):
            problems.append(f"lower bound {low:g}, Params {b}")
        if b.get("le", b.get("lt")) != high:
            problems.append(f"upper bound {high:g}, Params {b}")
    elif m := re.fullmatch(r"\(([-\d.e]+), ([-\d.e]+)\]", text):
        if b.get("gt") != float(m[1]) or b.get("le") != float(m[2]):
            problems.append(f"({m[1]}, {m[2]}], Params {b}")
    elif m := re.fullmatch(r">= ([-\d.e]+)", text):
        if b.get("ge") != float(m[1]):
            problems.append(f">= {m[1]}, Params {b}")
    elif re.fullmatch(r"[a-z_]+(, [a-z_]+)+", text):
        values = ({"true", "false"} if field.annotation is bool
                  else {shown(v) for v in typing.get_args(field.annotation)})
        if set(text.split(", ")) != values:
            problems.append(f"values {text}, Params {sorted(values)}")
    elif re.fullmatch(r"[\d, ]+", text):
        values = {shown(v) for v in typing.get_args(field.annotation)}
        if set(text.split(", ")) != values:
            problems.append(f"values {text}, Params {sorted(values)}")
    return problems


def stale_lines(cls) -> list[str]:
    """Each disagreement between ``cls``'s docstring table and its Params, one line each."""
    rows = table(cls.__doc__ or "")
    fields = cls.Params.model_fields
    problems = [f"{name}: in the table, not in Params" for name in rows if name not in fields]
    problems += [f"{name}: not in the table" for name in fields if name not in rows]
    for name, field in fields.items():
        row = rows.get(name)
        if row is None:
            continue
        default = field.default_factory() if field.default_factory else field.default
        if default is not PydanticUndefined and not same_default(row["Default"], default):
            problems.append(f"{name}: default {row['Default']!r} in the table, "
                            f"{shown(default)!r} in Params")
        if row.get("Range"):
            problems += [f"{name}: range {p}" for p in range_problems(row["Range"], field)]
    return problems


def example_plugin():
    sys.path.insert(0, str(ROOT / "examples" / "plugin"))
    try:
        from shadowbench_hwpcf.hardware_pcf import HardwarePCF
    finally:
        sys.path.pop(0)
    return HardwarePCF


@pytest.mark.parametrize("name", [*registry.techniques(), "example plugin hwpcf"])
def test_the_docstring_table_says_what_params_say(name):
    cls = example_plugin() if name.startswith("example") else registry.get(name)
    assert stale_lines(cls) == []


def test_a_stale_table_is_caught():
    """The issue's case: a table saying 1.5 where Params says 0.0, and a range 16 .. 4096 where
    Params allow 8192. Catches a check of the names alone (the registry test before this)."""
    from pydantic import Field

    from harness.technique import TechniqueParams

    class Stale:
        """A technique whose table was not updated.

        =================  ===============================  =======  ===========
        Parameter          Meaning                          Default  Range
        =================  ===============================  =======  ===========
        ``res``            map width and height, texels     1024     16 .. 4096
        ``normal_offset``  along the normal, texels         1.5      >= 0
        ``fit``            how the map is fitted            tight    tight, loose
        =================  ===============================  =======  ===========
        """

        class Params(TechniqueParams):
            res: int = Field(1024, ge=16, le=8192)
            normal_offset: float = Field(0.0, ge=0)
            fit: typing.Literal["tight", "loose", "sphere"] = "tight"

    assert stale_lines(Stale) == [
        "res: range upper bound 4096, Params {'ge': 16, 'le': 8192}",
        "normal_offset: default '1.5' in the table, '0.0' in Params",
        "fit: range values tight, loose, Params ['loose', 'sphere', 'tight']"]


def test_list_warns_of_an_editable_install_not_installed_again(tmp_path, monkeypatch, capsys):
    """An editable install whose pyproject.toml declares a technique added since it was
    installed (its metadata holds ``a``, the file ``a`` and ``b``): list warns, naming the
    distribution, the missing entry point and the command. Catches the warning missing (the
    entry point silently absent until reinstalled)."""
    import json

    from harness.cli import main

    source, site = tmp_path / "src", tmp_path / "site"
    source.mkdir()
    (source / "pyproject.toml").write_text(
        '[project]\nname = "shadowbench-fake"\n\n'
        '[project.entry-points."shadowbench.techniques"]\n'
        'a = "fake:A"\nb = "fake:B"\n')
    info = site / "shadowbench_fake-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: shadowbench-fake\n"
                                   "Version: 0.1\n")
    (info / "entry_points.txt").write_text("[shadowbench.techniques]\na = fake:A\n")
    (info / "direct_url.json").write_text(json.dumps(
        {"url": source.as_uri(), "dir_info": {"editable": True}}))
    monkeypatch.syspath_prepend(str(site))
    registry.techniques.cache_clear()
    try:
        assert main(["list", "--scene-file", str(ROOT / "scenes.yaml")]) == 0
    finally:
        monkeypatch.undo()
        registry.techniques.cache_clear()
    warnings = [line for line in capsys.readouterr().err.splitlines()
                if "shadowbench-fake" in line]
    assert warnings == [
        f"warning: shadowbench-fake is installed in editable mode and {source / 'pyproject.toml'} "
        f"has other techniques than its installed entry points (declared but not installed: "
        f"b): install it again: pip install -e {source}"]
