"""Timing statistics and machine load: pure functions over samples and CPU counters.

``median_interval`` gives a frame-time median with a 95% interval of the median, by order
statistics (distribution-free: the binomial count of samples below the median) or by a
seeded percentile bootstrap. ``cpu_sample``, ``others_time`` and ``contention`` measure how much of the
machine's CPU time other processes used during a window (``/proc/stat`` for the whole
machine, ``getrusage(RUSAGE_SELF)`` for this process with all its threads, llvmpipe's
rasterizer threads included).
"""

from __future__ import annotations

import math
import os
import resource
from dataclasses import dataclass
from pathlib import Path

import numpy as np

STATISTICS = ("order", "bootstrap")
CONFIDENCE = 0.95
BOOTSTRAP_RESAMPLES = 2000
# A run is noisy when other processes used more than this share of the machine's CPU time
# while it was timed: llvmpipe runs one rasterizer thread per core, so on a machine that busy
# its frames lost about that share of their CPU.
NOISY_CONTENTION = 0.10
# The run summary and the dashboard warn when more than this share of the timed runs is noisy.
NOISY_RUNS_SHARE = 0.05
# GL renderers that rasterise on the CPU: no GPU timer queries, and times that rank CPU cost.
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "lavapipe")


def too_noisy(noisy: int, timed: int) -> bool:
    """Whether ``noisy`` of ``timed`` runs earn the warning."""
    return noisy > NOISY_RUNS_SHARE * timed


def is_software_renderer(renderer: str) -> bool:
    return any(name in renderer.lower() for name in SOFTWARE_RENDERERS)


def order_statistic_ranks(n: int, confidence: float = CONFIDENCE) -> tuple[int, int]:
    """1-based ranks (l, n + 1 - l) of the narrowest symmetric order-statistic interval whose
    coverage of the median, 1 - 2 P(B <= l - 1) with B ~ Binomial(n, 1/2), is at least
    ``confidence``. Below n = 6 no such interval reaches 95%: then (1, n), whose coverage is
    1 - 2^(1 - n)."""
    if n < 1:
        raise ValueError(f"need at least one sample, got {n}")
    best, below = 1, 0.0  # below: P(B <= rank - 1)
    for rank in range(1, (n + 1) // 2 + 1):
        below += math.comb(n, rank - 1) / 2 ** n
        if 1 - 2 * below < confidence:
            break
        best = rank
    return best, n + 1 - best


def median_interval(samples, *, method: str = "order", confidence: float = CONFIDENCE,
                    seed: int = 0) -> tuple[float, float, float]:
    """(median, low, high): the sample median and a ``confidence`` interval of the population
    median.

    ``order``: the order statistics of :func:`order_statistic_ranks` (distribution-free, exact
    coverage for continuous samples; below 6 samples it is [min, max] with less coverage).
    ``bootstrap``: percentiles of the medians of ``BOOTSTRAP_RESAMPLES`` resamples drawn with a
    generator seeded by ``seed`` (reproducible)."""
    x = np.sort(np.asarray(samples, dtype=float).ravel())
    if x.size == 0:
        raise ValueError("no samples")
    if not np.all(np.isfinite(x)):
        raise ValueError("samples must be finite")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    median = float(np.median(x))
    if method == "order":
        low, high = order_statistic_ranks(x.size, confidence)
        return median, float(x[low - 1]), float(x[high - 1])
    if method == "bootstrap":
        rng = np.random.default_rng(seed)
        medians = np.median(rng.choice(x, size=(BOOTSTRAP_RESAMPLES, x.size)), axis=1)
        tail = (1 - confidence) / 2 * 100
        low, high = np.percentile(medians, [tail, 100 - tail])
        return median, float(min(low, median)), float(max(high, median))
    raise ValueError(f"method must be one of {', '.join(STATISTICS)}, got {method!r}")


@dataclass(frozen=True)
class CpuSample:
    """CPU seconds at one instant: the machine's busy and total time (all cores), and this
    process's own time (every thread)."""

    busy: float
    total: float
    own: float


_PROC_STAT = Path("/proc/stat")


def cpu_sample() -> CpuSample | None:
    """Counters now; None where the system has no ``/proc/stat``."""
    try:
        with _PROC_STAT.open() as f:
            fields = f.readline().split()
    except OSError:
        return None
    if not fields or fields[0] != "cpu":
        return None
    # user nice system idle iowait irq softirq steal (guest time is already inside user)
    ticks = [int(v) for v in fields[1:9]]
    tick = os.sysconf("SC_CLK_TCK")
    idle = ticks[3] + ticks[4]
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return CpuSample(busy=(sum(ticks) - idle) / tick, total=sum(ticks) / tick,
                     own=usage.ru_utime + usage.ru_stime)


def others_time(start: CpuSample, end: CpuSample) -> tuple[float, float]:
    """(CPU seconds other processes used, CPU seconds the machine had) between two samples.

    The machine counters advance in clock ticks (10 ms) while this process's time is exact,
    so over a short window the difference can come out slightly negative; it is kept as is,
    so that sums over many windows stay unbiased (clip only the final share)."""
    return (end.busy - start.busy) - (end.own - start.own), end.total - start.total


def contention(others_s: float, capacity_s: float) -> float | None:
    """The share of the machine's CPU time used by other processes, in [0, 1]; None when the
    window saw no clock tick."""
    if capacity_s <= 0:
        return None
    return min(max(others_s / capacity_s, 0.0), 1.0)
