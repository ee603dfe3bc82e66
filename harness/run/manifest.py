"""The manifest, written when a sweep starts and when it ends: DIR/manifest.json says what
produced DIR (versions, GL, machine, git, the experiment) and how each invocation ended."""

from __future__ import annotations

import errno
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

from .. import config as cfg
from .. import results
from ..gl import measure as pass_measure
from ..gl.measure import default_timer
from ..machine.timing import CONFIDENCE, NOISY_CONTENTION
from ..technique import registry
from .measure import BATCH_BYTES, BATCH_RESIDENT, BATCH_RUNS, UNSEEN_BYTES_PER_TRIANGLE
from .plan import Plan


# a read-only look: without it `git status` takes .git/index.lock to refresh the index, and a
# sweep's manifest would collide with the user's own git commands in the checkout
GIT = ("git", "--no-optional-locks")


def _git_commit() -> str:
    try:
        here = Path(__file__).resolve().parent
        return subprocess.run([*GIT, "-C", str(here), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip() + f" ({os.cpu_count()} logical)"
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _nvidia_gpus() -> list[dict]:
    """Name and driver of each NVIDIA GPU (empty without nvidia-smi)."""
    try:
        out = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total",
                              "--format=csv,noheader"], capture_output=True, text=True,
                             timeout=20).stdout
    except (OSError, subprocess.SubprocessError):
        return []
    keys = ("name", "driver", "memory")
    return [dict(zip(keys, (f.strip() for f in line.split(",")))) for line in out.splitlines()
            if line.strip()]


def _version(module: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(module)
    except PackageNotFoundError:
        return ""


def _git_dirty() -> bool | None:
    try:
        here = Path(__file__).resolve().parent
        out = subprocess.run([*GIT, "-C", str(here), "status", "--porcelain",
                              "--untracked-files=no"], check=False, capture_output=True,
                             text=True, timeout=10)
        return bool(out.stdout.strip()) if out.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        return None


def _meshes(config, source: Path | None) -> list[dict]:
    """Each mesh file of the scene (its description and the file its paths are relative to)
    as built: its triangles, parts (open ones: not closed), the zero-area triangles dropped
    from it, and what it holds that defines no triangle, skipped and counted by kind
    (harness.config.mesh_obj)."""
    out = []
    for obj in config.objects:
        if isinstance(obj, cfg.MeshFile):
            parts = cfg.mesh_parts(cfg.resolve_mesh_path(source or Path("."), obj), obj.up)
            out.append({"path": obj.label, "triangles": parts.triangles, "parts": len(parts.names),
                        "open_parts": parts.closed.count(False),
                        "degenerate_dropped": parts.dropped, "skipped": dict(parts.skipped)})
    return out


MANIFEST_FILE = "manifest.json"


def read_manifest(out_dir: Path) -> dict:
    """DIR/manifest.json ({} when missing or empty); a ConfigError when it is not ours."""
    path = Path(out_dir) / MANIFEST_FILE
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return {}
    except UnicodeDecodeError:
        raise _not_a_manifest(path) from None
    if not text.strip():
        return {}  # written, then lost in a crash before it reached the disk: rewritten now
    try:
        manifest = json.loads(text)
    except ValueError:
        raise _not_a_manifest(path) from None
    invocations = manifest.get("invocations", []) if isinstance(manifest, dict) else None
    if not isinstance(invocations, list) or not all(isinstance(i, dict) for i in invocations):
        raise _not_a_manifest(path)
    return manifest


def _not_a_manifest(path: Path) -> cfg.ConfigError:
    return cfg.ConfigError(f"{path}: not a shadowbench manifest; use another folder or move the "
                           "file away")


def _finished(invocations: list[dict]) -> str | None:
    """When DIR's runs were last added to, once the latest invocation has completed: the end
    of the last invocation that rendered something (a rerun with nothing left to render
    leaves it as it was); None while the latest has not completed."""
    if invocations[-1].get("status") != "complete":
        return None
    worked = [i["finished"] for i in invocations
              if (i.get("runs_rendered") or i.get("runs_retimed")) and i.get("finished")]
    return worked[-1] if worked else invocations[-1].get("finished")


# Kept free while a sweep runs, so that its manifest can still say how it ended on a full disk.
SPACE_RESERVE = ".space-reserve"
SPACE_RESERVE_BYTES = 1 << 16


def write_manifest(out_dir: Path, plan: Plan, context, session: dict) -> None:
    """Record what produced DIR, merged into what DIR's manifest holds already: every
    invocation into DIR is kept, whatever experiment or scenes it ran (one still ``running``
    when another starts was killed: ``interrupted``), with its experiment, scenes, runs and
    notes; ``scenes`` keeps every scene's description (this plan's replacing its own);
    ``experiments`` lists each experiment run into DIR. ``started`` is the first invocation's
    start, ``finished`` as :func:`_finished` says; ``experiment``, ``experiment_hash``, ``cost``,
    ``runs_planned`` and the machine's description are the latest invocation's.
    When the disk is full, the space reserve is given up to write it."""
    previous = read_manifest(out_dir)
    earlier = [dict(i, status="interrupted") if i.get("status") == "running" else i
               for i in previous.get("invocations", []) if i.get("id") != session["id"]]
    invocations = earlier + [session]
    scenes = previous.get("scenes") if isinstance(previous.get("scenes"), dict) else {}
    scenes = {**scenes, **{name: {"description": config.description,
                                  "effects": list(config.effects),
                                  "meshes": _meshes(config, source)}
                           for name, config, source in plan.described()}}
    experiment = {"experiment": plan.experiment_path, "experiment_hash": plan.experiment_hash}
    experiments = [e for e in previous.get("experiments", []) if isinstance(e, dict)
                   and e != experiment] + [experiment]
    counters_missing = pass_measure.pipeline_statistics_missing()
    manifest = {
        "shadowbench": _version(registry.own_distribution()),
        "versions": {name: _version(dist) for name, dist in (
            ("pyrender", "scikit-robot-pyrender"), ("PyOpenGL", "PyOpenGL"),
            ("mitsuba", "mitsuba"), ("drjit", "drjit"), ("numpy", "numpy"),
            ("trimesh", "trimesh"))},
        "python": sys.version.split()[0],
        "gl": {"platform": context.platform, "vendor": context.vendor,
               "renderer": context.renderer, "version": context.version,
               "timer": default_timer(context.renderer),
               # the work counters (vertex_invocations, ...): empty columns where unavailable
               "pipeline_statistics": ({"available": False, "why": counters_missing}
                                       if counters_missing else {"available": True})},
        "timing": {"interval": f"{CONFIDENCE:.0%} interval of the median",
                   "noisy_contention": NOISY_CONTENTION, "batch_bytes": BATCH_BYTES,
                   "batch_runs": BATCH_RUNS, "batch_resident_bytes": BATCH_RESIDENT,
                   "unseen_bytes_per_triangle": UNSEEN_BYTES_PER_TRIANGLE},
        "gpu": _nvidia_gpus(),
        "cpu": _cpu(),
        "git_commit": _git_commit(),
        "git_dirty": _git_dirty(),
        "experiment": plan.experiment_path,
        "experiment_hash": plan.experiment_hash,
        "cost": plan.cost,
        "runs_planned": len(plan.runs),
        "experiments": experiments,
        "scenes": scenes,
        "started": invocations[0].get("started") or session["started"],
        "finished": _finished(invocations),
        "status": session["status"],
        "invocations": invocations,
    }
    text = json.dumps(manifest, indent=2).encode()
    try:
        results.replace_atomically(out_dir / MANIFEST_FILE, lambda f: f.write(text))
    except OSError as e:
        reserve = out_dir / SPACE_RESERVE
        if e.errno != errno.ENOSPC or not reserve.is_file():
            raise
        reserve.unlink()
        results.replace_atomically(out_dir / MANIFEST_FILE, lambda f: f.write(text))
