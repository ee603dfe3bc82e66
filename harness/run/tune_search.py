"""One point's search, below :mod:`harness.run.tune`: an Optuna study (TPE with constraints) over
a technique's declared tunable settings at one point of its quality curve, asked and told one
trial at a time so that the tune can render the trials of every point together.

The objective is ``edge_mae``; the constraints are ``acne_pct <= ACNE_LIMIT`` and ``leak_pct <=
leak_limit`` (the baseline's at defaults plus a margin, :mod:`harness.analysis.tuning`). The
first trial is the point's own setting (the defaults), so a search never ends worse than them
when they qualify. A study's sampler is seeded from ``--seed`` and the point alone, so a rerun
asks the same settings in the same order (their run ids are in DIR: nothing is rendered
again) whatever other points are tuned beside it.
"""

from __future__ import annotations

import hashlib
import math
import warnings
from dataclasses import dataclass, field

from ..analysis.tuning import ACNE_LIMIT
from ..config import ConfigError

# a suggestion that the technique's Params refuse (pcf's bias_max below bias_min) is told as
# failed and asked again, at most this many times the budget in all
ASKS_PER_RUN = 4
# random settings before TPE models the results: a third of the budget, at most Optuna's 10
STARTUP_SHARE = 3


def metric(row: dict, name: str) -> float:
    """A row's number (a stored row holds text), NaN where it has none."""
    try:
        value = float(row.get(name))
    except (TypeError, ValueError):
        return math.nan
    return value


@dataclass
class Tried:
    """One setting the search ran: its parameters, its row's metrics, the constraints."""

    params: dict
    run_id: str
    ok: bool
    edge_mae: float = math.nan
    acne_pct: float = math.nan
    leak_pct: float = math.nan
    violation: float = math.inf  # how far past the limits (0: meets them)


def _constraints(trial) -> list[float]:
    return trial.user_attrs.get("constraints", [1.0, 1.0])


def study_seed(seed: int, *names: str) -> int:
    """A sampler seed from ``--seed`` and the point's names (stable across Python runs)."""
    text = "|".join([str(seed), *names])
    return int(hashlib.sha256(text.encode()).hexdigest()[:8], 16)


@dataclass
class Search:
    """The search of one scene's view, technique and point (``point``: its parameters, every
    one present); ``space``: the tunable settings searched (``{name: declaration}``)."""

    point: dict
    space: dict
    budget: int
    seed: int
    tried: list[Tried] = field(default_factory=list)
    asks: int = 0

    def __post_init__(self):
        import optuna

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        with warnings.catch_warnings():  # multivariate TPE is marked experimental
            warnings.simplefilter("ignore")
            sampler = optuna.samplers.TPESampler(
                seed=self.seed, constraints_func=_constraints, multivariate=True,
                n_startup_trials=max(1, min(10, self.budget // STARTUP_SHARE)))
        self.study = optuna.create_study(direction="minimize", sampler=sampler)
        self.study.enqueue_trial({name: self.point[name] for name in self.space})
        self.pending = None  # the trial asked and not told yet

    @property
    def done(self) -> bool:
        return len(self.tried) >= self.budget or self.asks >= self.budget * ASKS_PER_RUN

    def ask(self, validate) -> dict | None:
        """The next setting to run (validated by ``validate(params)``, which raises ConfigError
        for a setting the technique refuses), or None when the budget is spent."""
        import optuna

        while not self.done:
            with warnings.catch_warnings():  # a point's setting outside a declared range
                warnings.simplefilter("ignore")
                trial = self.study.ask()
                values = {name: _suggest(trial, name, declared)
                          for name, declared in self.space.items()}
            self.asks += 1
            try:
                params = validate({**self.point, **values})
            except ConfigError:
                self.study.tell(trial, state=optuna.trial.TrialState.FAIL)
                continue
            self.pending = trial
            return params
        return None

    def tell(self, params: dict, row: dict, leak_limit: float) -> None:
        """The row of the setting last asked, against the limits."""
        import optuna

        trial, self.pending = self.pending, None
        if row.get("status") != "ok":
            self.tried.append(Tried(params, row["run_id"], ok=False))
            self.study.tell(trial, state=optuna.trial.TrialState.FAIL)
            return
        tried = Tried(params, row["run_id"], ok=True, edge_mae=metric(row, "edge_mae"),
                      acne_pct=metric(row, "acne_pct"), leak_pct=metric(row, "leak_pct"))
        over = [tried.acne_pct - ACNE_LIMIT, tried.leak_pct - leak_limit]
        over = [o if math.isfinite(o) else 1e9 for o in over]
        tried.violation = sum(max(o, 0.0) for o in over)
        self.tried.append(tried)
        if not math.isfinite(tried.edge_mae):
            self.study.tell(trial, state=optuna.trial.TrialState.FAIL)
            return
        trial.set_user_attr("constraints", over)
        self.study.tell(trial, tried.edge_mae)

    def best(self) -> tuple[Tried | None, bool]:
        """The setting chosen and whether it meets the limits: the lowest edge_mae among those
        that do; where none does, the closest (least total excess over the limits, then the
        lowest edge_mae). None when no setting ran."""
        ran = [t for t in self.tried if t.ok and math.isfinite(t.edge_mae)]
        if not ran:
            return None, False
        meeting = [t for t in ran if t.violation == 0]
        if meeting:
            return min(meeting, key=lambda t: t.edge_mae), True
        return min(ran, key=lambda t: (t.violation, t.edge_mae)), False


def _suggest(trial, name: str, declared: tuple):
    kind = declared[0]
    if kind == "choice":
        return trial.suggest_categorical(name, list(declared[1]))
    if kind == "int":
        return trial.suggest_int(name, int(declared[1]), int(declared[2]))
    return trial.suggest_float(name, float(declared[1]), float(declared[2]), log=kind == "log")
