"""Plugins cannot break the harness (issue 35): real plugin distributions (tests/data/plugins),
installed beside the built-ins as a user installs them and found through the entry point alone.

- smbias: sm's class with another bias. It inherits sm's ``baseline = True`` as a class
  attribute, and is not a second baseline: list, run, report and compare all work.
- smbase: sm's class declaring ``baseline = True`` in its own body: a one-line error (exit 2)
  at list and run naming both distributions and the fix; report and compare of a folder that
  never ran it still work.
- badimport: a module that fails to import: listed as broken with its error; the others run.
"""

import csv
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import ROOT

PLUGINS = ROOT / "tests" / "data" / "plugins"
SHADOWBENCH = Path(sys.executable).with_name("shadowbench")
SCENES = str(ROOT / "scenes.yaml")

EXPERIMENT = """\
scenes: [box_plane]
techniques: {sm: {}, smbias: {}}
resolutions: [[48, 32]]
frames: 1
warmup: 0
reference: {samples: 1}
"""


def shadowbench(env, cwd, *args, timeout=300):
    return subprocess.run([str(SHADOWBENCH), *map(str, args)], env=env, cwd=cwd,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def smbias_run(plugin_env, tmp_path_factory):
    """(environment with smbias installed, a results folder of sm and smbias on box_plane)."""
    env = plugin_env(PLUGINS / "smbias")
    work = tmp_path_factory.mktemp("smbias")
    (work / "plugin.yaml").write_text(EXPERIMENT)
    run = shadowbench(env, work, "run", "plugin.yaml", "--scene-file", SCENES, "--out", "out",
                      "--quiet")
    assert run.returncode == 0, run.stderr
    return env, work / "out", run.stderr


def test_a_subclass_of_sm_is_no_second_baseline(smbias_run):
    """list, run, report and compare all work with smbias installed, and the run names the
    plugin it included. Catches the baseline read through inheritance (``cls.baseline``): the
    run then exits 2 with "techniques sm (...), smbias (...) each declare baseline" (before
    this issue, list and run passed and report failed on every folder)."""
    env, out, run_log = smbias_run
    assert "installed plugins in this plan: smbias (shadowbench-smbias)" in run_log
    with (out / "results.csv").open() as f:
        rows = {r["technique"]: r for r in csv.DictReader(f)}
    assert set(rows) == {"sm", "smbias"} and {r["status"] for r in rows.values()} == {"ok"}
    assert '"bias": 0.05' in rows["smbias"]["params"]
    listed = shadowbench(env, out.parent, "list", "--scene-file", SCENES)
    assert listed.returncode == 0, listed.stderr
    assert "smbias     sm with a larger default bias" in listed.stdout
    assert "(plugin: shadowbench-smbias)" in listed.stdout
    report = shadowbench(env, out.parent, "report", out)
    assert report.returncode == 0, report.stderr
    assert (out / "index.html").is_file()
    compared = shadowbench(env, out.parent, "compare", out, out)
    assert compared.returncode == 0, compared.stderr


def test_two_declared_baselines_are_one_line_at_list_and_run(plugin_env, smbias_run, tmp_path):
    """With smbase installed too, list and run exit 2 with one line naming both techniques,
    their distributions and the fix; report and compare of the folder that never ran smbase
    still work. Catches baseline() asked of every installed technique in report (exit 2 on a
    folder of sm and smbias) and the check left out of list (exit 0)."""
    _, out, _ = smbias_run
    env = plugin_env(PLUGINS / "smbias", PLUGINS / "smbase")
    message = ("shadowbench: techniques sm (distribution hard-shadow-bench), smbase (distribution "
               "shadowbench-smbase) each declare baseline = True in their class; one baseline at "
               "most: remove the line from all but one, or uninstall one of the distributions")
    listed = shadowbench(env, tmp_path, "list", "--scene-file", SCENES)
    assert listed.returncode == 2 and listed.stderr.splitlines() == [message], listed.stderr
    run = shadowbench(env, tmp_path, "run", "--scene-file", SCENES, "--scenes", "box_plane",
                      "--techniques", "sm", "--out", tmp_path / "out")
    assert run.returncode == 2 and run.stderr.splitlines() == [message], run.stderr
    assert not (tmp_path / "out").exists()
    report = shadowbench(env, tmp_path, "report", out)
    assert report.returncode == 0, report.stderr
    compared = shadowbench(env, tmp_path, "compare", out, out)
    assert compared.returncode == 0, compared.stderr


def test_a_plugin_that_fails_to_import_is_listed_broken_and_the_others_run(plugin_env,
                                                                           tmp_path):
    """badimport's module imports a package that is not installed: list exits 0 and names it
    broken with the ModuleNotFoundError and its distribution; a run of every technique leaves
    it out, saying so, and plans the built-ins. Catches an entry point's import error let out
    of the registry (every command: internal error, exit 1)."""
    env = plugin_env(PLUGINS / "badimport")
    listed = shadowbench(env, tmp_path, "list", "--scene-file", SCENES)
    assert listed.returncode == 0, listed.stderr
    broken = [line for line in listed.stdout.splitlines() if "BROKEN" in line]
    assert broken == ["  badimport  BROKEN, left out of every run: cannot import "
                      "shadowbench_badimport:Nothing: ModuleNotFoundError: No module named "
                      "'shadowbench_no_such_dependency' [shadowbench-badimport]"], broken
    assert "\n  sm         shadow map" in listed.stdout
    plan = shadowbench(env, tmp_path, "plan", "--scene-file", SCENES, "--scenes", "box_plane")
    assert plan.returncode == 0, plan.stderr
    assert "left out, broken: badimport: cannot import" in plan.stdout
    assert "sm 1" in plan.stdout
    named = shadowbench(env, tmp_path, "plan", "--scene-file", SCENES, "--techniques",
                        "badimport")
    assert named.returncode == 2 and "--techniques: badimport is broken: cannot import" \
        in named.stderr, named.stderr
