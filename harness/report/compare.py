"""``shadowbench compare A B``: the runs two results folders have in common, matched by scene,
image size, technique and parameters (by value: ``1`` and ``1.0`` are one setting), and what
changed from A to B in time and in error. A run found in one folder only is paired with one of
the other's of the same scene, size and technique (the one that differs in the fewest
parameters), and shown with its changed parameters (``k: 16 → 4``); what stays unpaired is
listed by name. A line names a run by the parameters that tell it from its technique's other
runs there and the ones that changed, never all of them.

Time is worse (or better) only when B's is more than ``factor`` times A's (or less than
1/``factor``), each run's median lies outside the other run's timing interval
(``time_ms_ci_low``/``high``) and neither run is noisy (timed while other processes took the
CPU); where the ratio is beyond ``factor`` but one of those fails, the time is *undecided* and
the line says why (noisy, no interval, inside an interval). An error metric is worse when it
grew by more than ``tolerance`` of A's value (and by more than rounding); a run that was ok in
A and is not in B is worse. Only what got worse is starred. Like ``asv compare``: exit 0, or 1
when something got worse (a pair as a run in common). A folder that holds no shadowbench results
of this version, two folders with no run in common and none to pair, or two measured under
different cost policies (their times hold different work) are bad input (:class:`ConfigError`,
exit 2)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..config import ConfigError
from .plots import cost_policy, number
from .render import number as shown, render, write_page
from .stored import read_results

KEY = ["scene", "width", "height", "technique", "params_key"]
ERRORS = ("edge_mae", "wrong_pct", "mae")
ROUNDING = 1e-9  # error changes below this are equal


def _by_value(value):
    """A parameter's value as compared: a float that is a whole number as that integer."""
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def params_key(params: dict) -> str:
    """The parameters as one text, equal for equal settings (``k: 4`` and ``k: 4.0``)."""
    return json.dumps({k: _by_value(v) for k, v in params.items()}, sort_keys=True)


def load(folder: Path) -> pd.DataFrame:
    """The latest row of each run in ``folder`` (ConfigError when it holds no results)."""
    rows = read_results(folder)
    rows = rows.assign(params_key=rows["params"].map(params_key))
    return rows.drop_duplicates(subset=KEY, keep="last")


@dataclass
class Comparison:
    before: Path
    after: Path
    rows: list[dict]  # one per run in common or pair, worse first; a pair's "changed" is set
    only_before: list[str]  # the runs left unpaired, by name
    only_after: list[str]
    factor: float
    tolerance: float

    @property
    def common(self) -> int:
        return sum(not r["changed"] for r in self.rows)

    @property
    def paired(self) -> int:
        return sum(bool(r["changed"]) for r in self.rows)

    @property
    def worse(self) -> int:
        return sum(r["verdict"] == "worse" for r in self.rows)

    @property
    def better(self) -> int:
        return sum(r["verdict"] == "better" for r in self.rows)

    @property
    def undecided(self) -> int:
        return sum(r["verdict"] == "undecided" for r in self.rows)


def _interval(row) -> tuple[float, float] | None:
    """The run's timing interval; None without one, or where it has no width (a run of one
    frame: its spread is not known)."""
    low, high = number(row.get("time_ms_ci_low")), number(row.get("time_ms_ci_high"))
    return (low, high) if low is not None and high is not None and high > low else None


def _noisy(row) -> bool:
    return bool(number(row.get("noisy")))


def time_change(a, b, factor: float) -> tuple[str, float | None, str]:
    """(verdict, B / A, why): "worse" or "better" only where the ratio is beyond ``factor``,
    each run's median lies outside the other run's interval and neither run is noisy (timed
    while other processes took the CPU); "undecided" where the ratio is beyond ``factor`` but
    one of those is not so (``why`` says which); else "same"."""
    ta, tb = number(a.get("time_ms")), number(b.get("time_ms"))
    if not ta or not tb:
        return "same", None, ""
    ratio = tb / ta
    if 1 / factor <= ratio <= factor:
        return "same", ratio, ""
    ia, ib = _interval(a), _interval(b)
    if _noisy(a) or _noisy(b):
        return "undecided", ratio, "noisy"
    if ia is None or ib is None:
        return "undecided", ratio, "no interval"
    if not (tb < ia[0] or tb > ia[1]) or not (ta < ib[0] or ta > ib[1]):
        return "undecided", ratio, "inside an interval"
    return ("worse" if ratio > 1 else "better"), ratio, ""


def error_change(a: float, b: float, tolerance: float) -> str:
    if not (math.isfinite(a) and math.isfinite(b)):
        return "same"
    margin = tolerance * abs(a) + ROUNDING
    return "worse" if b - a > margin else "better" if a - b > margin else "same"


def _value(row, column: str) -> float:
    v = number(row.get(column))
    return math.nan if v is None else v


def compare(before: str | Path, after: str | Path, *, factor: float = 1.1,
            tolerance: float = 0.05) -> Comparison:
    before, after = Path(before), Path(after)
    a, b = load(before), load(after)
    policy_a, policy_b = cost_policy(a), cost_policy(b)
    if policy_a != policy_b:
        raise ConfigError(f"{before} (cost: {policy_a}) and {after} (cost: {policy_b}): "
                          "measured under different cost policies, their times hold different "
                          "work; compare folders of one policy")
    keys_a, keys_b = set(map(tuple, a[KEY].values)), set(map(tuple, b[KEY].values))
    only_a = a[[k not in keys_b for k in map(tuple, a[KEY].values)]]
    only_b = b[[k not in keys_a for k in map(tuple, b[KEY].values)]]
    matches = _common(a, b)
    pairs, left_a, left_b = pair_changed(only_a, only_b)
    if not matches and not pairs:
        raise ConfigError(f"{before} and {after}: no run in common (same scene, image size, "
                          "technique and parameters) and none to pair (same scene, image size "
                          "and technique)")
    varying = _varying(pd.concat([a, b], ignore_index=True))
    rows = [_row(ra, rb, factor, tolerance, varying) for ra, rb in matches + pairs]
    order = {"worse": 0, "better": 1, "undecided": 2, "same": 3}
    rows.sort(key=lambda r: (order[r["verdict"]], r["scene"], r["size"], r["technique"],
                             r["setting"], r["changed"]))
    return Comparison(before, after, rows, [run_name(r) for r in left_a],
                      [run_name(r) for r in left_b], factor, tolerance)


GROUP = ["scene", "width", "height", "technique"]


def _group(row) -> tuple:
    return tuple(row[k] for k in GROUP)


def _varying(rows) -> dict[tuple, list[str]]:
    """Per scene, size and technique, the parameters whose value differs among its runs in
    either folder: what a line names a run by."""
    out = {}
    for key, g in rows.groupby(GROUP, sort=False):
        settings = [json.loads(k) for k in g["params_key"]]
        names = sorted({n for p in settings for n in p})
        out[key] = [n for n in names if len({json.dumps(p.get(n)) for p in settings}) > 1]
    return out


def _common(a, b) -> list[tuple[dict, dict]]:
    """(A's row, B's row) of each run in both folders (equal on KEY)."""
    in_b = {tuple(k): r for k, r in zip(b[KEY].values, b.to_dict("records"))}
    return [(r, in_b[tuple(k)]) for k, r in zip(a[KEY].values, a.to_dict("records"))
            if tuple(k) in in_b]


def _params(row) -> dict:
    return json.loads(row["params_key"])


def changed_params(ra, rb) -> dict[str, tuple]:
    """{parameter: (value in A, value in B)} for the parameters that differ."""
    pa, pb = _params(ra), _params(rb)
    return {k: (pa.get(k), pb.get(k)) for k in sorted(set(pa) | set(pb)) if pa.get(k) != pb.get(k)}


def pair_changed(only_a, only_b) -> tuple[list[tuple[dict, dict]], list[dict], list[dict]]:
    """Runs of one folder only, paired with the other's of the same scene, size and technique:
    the pairs that differ in the fewest parameters first, each run in one pair at most. Returns
    (pairs, A's runs left, B's runs left)."""
    runs_a, runs_b = only_a.to_dict("records"), only_b.to_dict("records")
    candidates = sorted(
        (len(changed_params(ra, rb)), i, j) for i, ra in enumerate(runs_a)
        for j, rb in enumerate(runs_b) if _group(ra) == _group(rb))
    used_a, used_b, pairs = set(), set(), []
    for _, i, j in candidates:
        if i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            pairs.append((runs_a[i], runs_b[j]))
    return (pairs, [r for i, r in enumerate(runs_a) if i not in used_a],
            [r for j, r in enumerate(runs_b) if j not in used_b])


def run_name(row) -> str:
    """``scene 512x512 pcf k=16, res=1024``: a run as the unpaired list names it (every
    parameter: nothing beside it tells it apart)."""
    params = ", ".join(f"{k}={v}" for k, v in _params(row).items())
    return f"{row['scene']} {int(row['width'])}x{int(row['height'])} {row['technique']} {params}"


def _row(ra: dict, rb: dict, factor: float, tolerance: float,
         varying: dict[tuple, list[str]]) -> dict:
    """One line of the comparison: a run in common, or a pair with its changed parameters."""
    changes = {}
    if ra["status"] == "ok" and rb["status"] != "ok":
        changes["status"] = "worse"
    elif ra["status"] != "ok" and rb["status"] == "ok":
        changes["status"] = "better"
    time_verdict, ratio, why = time_change(ra, rb, factor)
    changes["time_ms"] = time_verdict
    for metric in ERRORS:
        changes[metric] = error_change(_value(ra, metric), _value(rb, metric), tolerance)
    verdicts = set(changes.values())
    verdict = next(v for v in ("worse", "better", "undecided", "same")
                   if v in verdicts or v == "same")
    changed = changed_params(ra, rb)
    params = _params(rb)
    return {
        "scene": ra["scene"], "size": f"{int(ra['width'])}x{int(ra['height'])}",
        "technique": ra["technique"],
        # the parameters that tell the run from its technique's others here, less the changed
        "setting": " ".join(f"{k}={params.get(k)}" for k in varying.get(_group(rb), [])
                            if k not in changed),
        "changed": ", ".join(f"{k}: {x} → {y}" for k, (x, y) in changed.items()),
        "status": (ra["status"], rb["status"]), "ratio": ratio, "verdict": verdict,
        "changes": changes, "undecided": why,
        "time": [(number(r.get("time_ms")), _interval(r), _noisy(r)) for r in (ra, rb)],
        "errors": {metric: (_value(ra, metric), _value(rb, metric)) for metric in ERRORS}}


MARK = {"worse": "*", "better": "", "undecided": "", "same": ""}  # only a regression is starred
TIME_WORD = {"worse": "slower", "better": "faster", "same": ""}


def time_note(r: dict) -> str:
    """What the line says of its time: slower (starred), faster, or why it cannot tell."""
    verdict = r["changes"]["time_ms"]
    if verdict == "undecided":
        return f"? {r['undecided']}"
    return TIME_WORD[verdict] + (" *" if verdict == "worse" else "")


def error_text(r: dict, metric: str) -> str:
    """One value where it did not change, ``before → after`` where it did, starred where it
    got worse."""
    x, y = (shown(v) or "–" for v in r["errors"][metric])
    text = x if x == y else f"{x} → {y}"
    return text + (" *" if r["changes"][metric] == "worse" else "")


def text(c: Comparison, *, only_changed: bool = False) -> str:
    """The comparison as a plain table (``*``: got worse), then a summary line."""
    head = ["", "scene", "size", "technique", "time_ms", "ratio", "time"] + list(ERRORS) + [
        "setting"]
    lines = [head]
    for r in c.rows:
        if only_changed and r["verdict"] == "same":
            continue
        status = "" if r["status"] == ("ok", "ok") else f" ({r['status'][0]} → {r['status'][1]})"
        (ta, *_), (tb, *_) = r["time"]
        lines.append([MARK[r["verdict"]], r["scene"], r["size"], r["technique"] + status,
                      f"{shown(ta) or '–'} → {shown(tb) or '–'}",
                      f"{r['ratio']:.2f}" if r["ratio"] else "–", time_note(r)]
                     + [error_text(r, m) for m in ERRORS]
                     + ["; ".join(filter(None, [r["setting"],
                                                r["changed"] and f"changed {r['changed']}"]))])
    widths = [max(len(row[i]) for row in lines) for i in range(len(head) - 1)]
    out = ["  ".join(cell.ljust(w) for cell, w in zip(row, widths)) + "  " + row[-1]
           for row in lines]
    for where, names in ((c.before, c.only_before), (c.after, c.only_after)):
        if names:
            out.append(f"only in {where}, unpaired:")
            out += [f"  {name}" for name in names]
    out.append(summary(c))
    return "\n".join(line.rstrip() for line in out)


def summary(c: Comparison) -> str:
    """Two lines: what was matched, then what changed."""
    unsure = (f", {c.undecided} undecided (time moved beyond {c.factor:g}x, but a run is noisy "
              "or has no interval, or a median lies inside the other's)" if c.undecided else "")
    return (f"{c.common} runs in common, {c.paired} paired with changed parameters; "
            f"{len(c.only_before)} unpaired only in {c.before}, {len(c.only_after)} only in "
            f"{c.after}\n{c.worse} worse, {c.better} better{unsure}")


def write_html(c: Comparison, path: str | Path) -> Path:
    page = render("compare.html.j2", c=c, errors=ERRORS, summary=summary(c), mark=MARK,
                  time_note=time_note, error_text=error_text)
    return write_page(Path(path), page)
