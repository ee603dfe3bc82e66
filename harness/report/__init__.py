"""The dashboard: ``DIR/index.html`` built only from stored results (``results.csv``,
``manifest.json`` and the run arrays); it never renders.

One self-contained file: its stylesheet, its scripts (``static/charts.js``, a small SVG plotter,
and ``static/page.js``) and every image (WebP data URIs at the size shown) are inside it, so it
works copied on its own and offline. Images larger than shown are also written at native size
under ``DIR/images/``, which the viewer opens on a click when they are there.

The page's parts, one module each:

- ``overview``: per band of scene size, per technique its share of cost-accuracy fronts, its median
  cost ratio to the baseline technique (sm) at equal error and its worst case; the renderer's
  caveat; failures and noisy runs counted; the table of scenes (thumbnail, description, the
  cheapest good-enough pick);
- ``scene_section``: per scene the cost-accuracy plot (``plots``), which technique within each
  error threshold and time budget, every run in a table;
- ``viewer``: any run's reference, V, signed error, shaded image, worst edge crops and maps;
- ``scale``: with family scenes, cost at equal error against triangles, the fitted exponents,
  the fronts per size and the crossover table;
- ``stability``: scenes x techniques with failures, NaN/Inf and V outside [0, 1];
- ``cutouts``: per scene with alpha-tested casters, which techniques cut them out, which ran
  ignoring them (with their error) and which declined (with the reason);
- ``tuning``: in a folder ``shadowbench tune`` wrote (whose verdict is then given on the tuned
  runs, the defaults' beside), what tuning bought and the bias window's acne-against-leak curve;
- ``papers``: the Papers page; ``compare``: two results folders run by run.

Names and values from the results reach the page only through autoescaped templates
(``render``) and arrays are read only from inside the folder (``stored``). The scene sections,
most of the build's time (their images), are built in worker processes, one per core; what
those warn goes to ``DIR/warnings.log`` (:mod:`harness.machine.warnings_log`), never onto the
terminal.
"""

from __future__ import annotations

import datetime as dt
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

from .. import analysis
from ..analysis import tuning as tuned_runs  # not .tuning, this package's own view
from ..machine import warnings_log
from ..run.progress import QUIET, Progress
from ..technique import registry
from . import images, overview, plots
from .scale import scale_view
from .papers import build_papers_page, papers_link
from .render import render, write_page
from .scene_section import scene_section, shown_rows
from .cutouts import cutout_table
from .stability import stability_table
from .stored import Folder, slug
from .tuning import tuning_view
from .viewer import SceneImages

__all__ = ["build_report", "build_papers_page", "visibility_png"]


def visibility_png(v, covered, path: Path) -> None:
    """V as the dashboard shows it (grey, uncovered blue-grey), at native size."""
    images.write_png(images.visibility(v, covered), images.VISIBILITY, Path(path))


def build_report(out_dir: str | Path, *, shown_px: int = images.SHOWN_PX,
                 progress: str = QUIET) -> Path:
    """Write ``out_dir/index.html`` (and its native-size images) from the stored results;
    returns its path. ``shown_px``: the longer side of an image as the page shows it (larger
    images also get a native-size file). ``progress``: the mode of the scene sections'
    progress on stderr (``harness.run.progress``; none by default). ConfigError when the
    folder holds no results (``stored.read_results``)."""
    folder = Folder(out_dir)
    everything = folder.rows()
    meta = folder.manifest()
    current = analysis.current(everything)
    baseline = registry.baseline(among=set(everything["technique"]))  # a plugin not run here
    # cannot make this folder's report fail
    tuned = tuned_runs.has_tuning(current)
    if tuned:  # a tune folder: the verdict on the tuned runs, the defaults' beside
        with_tuning, defaults = current, tuned_runs.defaults_rows(current)
        current = tuned_runs.verdict_rows(current)
        everything = everything[everything["tuning"].isin(["best", "defaults"])]
    shown = shown_rows(everything, current)
    colours = plots.colours(shown["technique"])
    described = meta.get("scenes") if isinstance(meta.get("scenes"), dict) else {}
    cheapest = analysis.cheapest_at_error(current)
    budgets = analysis.best_within_budget(current)
    jobs = {name: (shown[shown["scene"] == name], current[current["scene"] == name],
                   cheapest[cheapest["scene"] == name], budgets[budgets["scene"] == name],
                   colours, (described.get(name) or {}).get("description"), shown_px)
            for name in dict.fromkeys(shown["scene"])}
    workers = min(len(jobs), _cpus())
    shown_progress = Progress(len(jobs), unit="scene", mode=progress)
    shown_progress.stage(f"{out_dir}: {len(shown)} runs, images of {len(jobs)} scenes on "
                         f"{workers} worker{'s' * (workers > 1)}")
    # one worker: a thread of this process, which a 2-second process start would not repay
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) \
            if workers > 1 else ThreadPoolExecutor(1) as pool:
        # the largest scenes first, so that no worker is left with one at the end
        # a worker process catches its own warnings; a thread's are this process's
        part = scene_part_quietly if workers > 1 else _scene_part_here
        pending = {name: pool.submit(part, folder.root, name, *jobs[name])
                   for name in sorted(jobs, key=lambda n: -len(jobs[n][0]))}
        page = dict(
            folder=str(out_dir), meta=meta,
            caveat=overview.caveat(meta, everything), counts=overview.counts(shown, current),
            experiments=overview.experiments(meta),
            hidden=len(everything) - len(shown),
            verdicts=overview.verdicts(current, shown, colours), colours=colours,
            defaults_verdicts=overview.verdicts(defaults, shown, colours) if tuned else None,
            tuning=tuning_view(with_tuning, colours) if tuned else None,
            baseline=baseline or "the baseline", stability=stability_table(shown),
            cutouts=cutout_table(shown),
            scale=scale_view(current, colours, baseline,
                             registry.rivals(set(current["technique"]))),
            theta=plots.theta(current, colours), papers=papers_link(folder.root))
        scenes, caught = [], []
        try:
            for name in jobs:
                section, notes, lines = pending[name].result()
                scenes.append(section)
                folder.notes.extend(notes)
                caught += lines
                shown_progress.step(f"{name}: {len(section['runs'])} runs")
        finally:
            shown_progress.close()
    # what the worker processes warned: into DIR/warnings.log as the command's own warnings
    warnings_log.append(folder.root, caught)
    return write_page(folder.root / "index.html", render(
        "index.html.j2", **page, scenes=scenes, notes=folder.notes,
        built=dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")))


def scene_part(root: Path, name: str, shown, current, cheapest, budgets,
               colours: dict[str, str], description: str | None,
               shown_px: int) -> tuple[dict, list[str]]:
    """One scene's section (``shown``, ``current``, ``cheapest`` and ``budgets`` cut to it)
    and the notes on what of its files could not be used. A process of its own: its images
    are most of the dashboard's time."""
    folder = Folder(root)
    section = scene_section(SceneImages(folder, name, shown_px), shown, current, cheapest, budgets,
                            colours, description)
    section["slug"] = slug(name)
    section["pick"] = overview.scene_pick(cheapest, name, [
        tuple(map(int, s.split("x"))) for s in section["sizes"]])
    section["failed"] = sum(r["status"] == "error" for r in section["runs"])
    return section, folder.notes


def scene_part_quietly(*args) -> tuple[dict, list[str], list[str]]:
    """:func:`scene_part` in a worker process, with the warnings it raised or logged as lines
    (a worker's own would reach the terminal: the command's catching is its process's only)."""
    with warnings_log.Caught() as caught:
        section, notes = scene_part(*args)
    return section, notes, caught.lines


def _scene_part_here(*args) -> tuple[dict, list[str], list[str]]:
    return (*scene_part(*args), [])


def _cpus() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
