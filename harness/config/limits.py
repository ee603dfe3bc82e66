"""Bottom of the config package: the numbers every scene and experiment must stay within,
and why; yaml_source, mesh_files and the two schemas above it check against these.

Every number must be finite, and within what the renderers can represent:

- coordinates, sizes and distances at most ``MAX_COORDINATE`` (1e7) in magnitude: vertices are
  float32, whose step is already one unit at 1e7;
- sizes, radii, heights and scales > 0 (a zero scale flattens an object to nothing);
- ``camera.far / camera.near`` at most ``MAX_DEPTH_RATIO`` (2^20): the camera pass writes a
  24-bit depth buffer cleared to 1 and keeps fragments with depth < 1. A point at distance d
  lies ``near (far - d) / ((far - near) d)`` below 1 in window depth, so with far/near = R every
  point nearer than far/2 is at least 2^24 / R steps in front of the cleared depth: 16 at the
  limit. At near 1e-7, far 1e9 a box 6 units away rounds to 1 and the GL view covers nothing;
- a scene's triangles at most ``DEFAULT_TRIANGLE_BUDGET`` (1,000,000), or the experiment's
  ``triangle_budget``: what keeps the whole process under 4 GiB resident at 1024^2 for every
  technique. Measured on the architecture family at 10^6 triangles (168 open parts, 965k
  shadow edges): the map techniques peak at 0.8 to 1.2 GiB (the reference's Mitsuba build
  included), shadow volumes' per-triangle volumes at 3.3 GiB. A family's size counts as its
  target (it lands at most there);
- a plan's runs at most ``DEFAULT_MAX_RUNS`` (5,000: about three hours at 2 s a run), or the
  experiment's ``max_runs`` (the command line's ``--max-runs``), itself at most ``MAX_RUNS``
  (1,000,000: about three weeks at 2 s a run, and a plan of that many RunSpecs already takes a
  few GiB). The planner counts a plan's runs from the grids' sizes before it makes any;
- scene names (they name folders under ``--out``) from ``NAME_PATTERN``: letters, digits,
  ``_``, ``-`` and ``.``, not starting with ``.``, at most 64 characters.
"""

import re

MAX_COORDINATE = 1e7
MAX_DEPTH_RATIO = 2 ** 20
DEFAULT_TRIANGLE_BUDGET = 1_000_000
DEFAULT_MAX_RUNS = 5_000
MAX_RUNS = 1_000_000
# degrees; no one benchmarks a narrower view, and toward 0 the projection's 1 / tan(fov / 2)
# overflows float32
MIN_FOV = 0.01
NAME_PATTERN = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,63}")
# shadowbench tune (harness.run.tune): the settings searched per scene, technique and point by
# default and at most (--budget), and the searches' seed by default (--seed). Here, below the
# command line: its parser names them without importing the runs' modules (two seconds of
# every command's start, --help and list included, before)
DEFAULT_TUNE_BUDGET = 24
MAX_TUNE_BUDGET = 1000
DEFAULT_TUNE_SEED = 0
