"""Every path stays inside --out: names, rereads, --out that cannot be a folder or is read-only,
foreign files, file modes, and the manifest's git call. Each test names the broken code it
catches."""

from __future__ import annotations

import os
import stat
import subprocess

import pytest
from helpers import (
    GOOD,
    PY,
    assert_one_line,
    needs_tmpfs,
    result_rows,
    run_cli,
    small_run,
    subprocess_env,
    sweep,
    write_scenes,
)

from harness import cli, config, results
from harness.run import manifest


def test_inside_resolves_and_refuses_paths_out_of_the_folder(tmp_path):
    """Catches: a containment check on the unresolved path (`..` or a link out passes)."""
    out = tmp_path / "out"
    (out / "arrays").mkdir(parents=True)
    (out / "link").symlink_to(tmp_path)
    assert results.inside(out, "arrays/a.npz") == (out / "arrays/a.npz").resolve()
    for escape in ("../x.npz", "arrays/../../x.npz", "/etc/passwd", "link/x.npz"):
        with pytest.raises(config.ConfigError, match="outside"):
            results.inside(out, escape)


def test_a_rerun_never_reads_arrays_outside_the_folder(tmp_path, gl_context):
    """Catches: a results.csv whose `array` points out of the folder being trusted. Before:
    the run counted as done and the row kept '../outside.npz'."""
    args = small_run(tmp_path)
    assert cli.main(args) == 0
    out = tmp_path / "out"
    rows = result_rows(out)
    outside = tmp_path / "outside.npz"
    (out / rows[0]["array"]).rename(outside)
    rows[0]["array"] = "../outside.npz"
    results.write_rows(out, rows)
    assert cli.main(args) == 0
    again = result_rows(out)
    assert again[0]["status"] == "ok"
    assert results.inside(out, again[0]["array"]).is_file()


@pytest.mark.parametrize("where", ["a file", "under a file"])
def test_out_that_cannot_be_a_folder(where, tmp_path, capsys):
    """Before: FileExistsError / NotADirectoryError tracebacks."""
    (tmp_path / "f").write_text("x")
    out = tmp_path / "f" if where == "a file" else tmp_path / "f" / "out"
    code, err = run_cli(sweep(write_scenes(tmp_path, {"s": GOOD}), out), capsys)
    assert_one_line(code, err, 2, str(out))


@needs_tmpfs
def test_out_on_a_read_only_file_system(tmp_path):
    """Before: an OSError (EROFS) traceback."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    (tmp_path / "ro").mkdir()
    script = (f"mount -t tmpfs -o ro,size=1m none {tmp_path}/ro && exec {PY} -m harness.cli run "
              f"--scene-file {scene_file} --techniques sm --out {tmp_path}/ro/out --quiet")
    proc = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True,
                          text=True, timeout=300, env=subprocess_env())
    err = proc.stderr.strip().splitlines()
    assert_one_line(proc.returncode, err, 2, f"{tmp_path}/ro/out", "Read-only file system")


FOREIGN = {
    "results.csv": ["name,value\nfoo,1\n", bytes(range(256))],
    "manifest.json": ["[1, 2, 3]", "{not json", b"\xff\xfe", '{"invocations": 3}'],
}


@pytest.mark.parametrize("name, content", [(n, c) for n, cs in FOREIGN.items() for c in cs])
def test_foreign_files_in_out_are_refused(name, content, tmp_path, capsys):
    """Catches: a results.csv or manifest.json of someone else in --out. Before: KeyError
    ('status') and AttributeError ('list' object has no attribute 'get') tracebacks; a broken
    manifest was silently replaced."""
    out = tmp_path / "out"
    out.mkdir()
    file = out / name
    file.write_bytes(content if isinstance(content, bytes) else content.encode())
    code, err = run_cli(sweep(write_scenes(tmp_path, {"s": GOOD}), out), capsys)
    assert_one_line(code, err, 2, str(file), "not a shadowbench")
    assert file.read_bytes() == (content if isinstance(content, bytes) else content.encode())
    assert {p.name for p in out.iterdir()} <= {name, ".lock"}


def test_arrays_and_results_get_the_umasks_mode(tmp_path, gl_context):
    """Catches: mkstemp's 0600 on stored arrays. Before: every .npz was 0600."""
    args = small_run(tmp_path)
    previous = os.umask(0o027)
    try:
        assert cli.main(args) == 0
    finally:
        os.umask(previous)
    out = tmp_path / "out"
    stored = [*out.rglob("*.npz"), out / "results.csv", out / "manifest.json"]
    assert len(stored) == 4
    assert {stat.S_IMODE(p.stat().st_mode) for p in stored} == {0o640}


@pytest.mark.parametrize("out", ["a file", "/proc/self/out", "/sys/out"])
def test_every_out_problem_names_out(out, tmp_path, capsys):
    """Before: '/proc/self/.lock: No such file or directory', and a file's message named only
    the path."""
    if out == "a file":
        out = tmp_path / "f"
        out.write_text("x")
    code, err = run_cli(sweep(write_scenes(tmp_path, {"s": GOOD}), out), capsys)
    assert_one_line(code, err, 2, f"--out {out}")


def test_the_manifest_runs_git_without_optional_locks(monkeypatch):
    """Before: `git status` took .git/index.lock, colliding with the user's git commands."""
    commands = []

    def fake_run(argv, **kwargs):
        commands.append(argv)
        return subprocess.CompletedProcess(argv, 0, stdout="", stderr="")

    monkeypatch.setattr(manifest.subprocess, "run", fake_run)
    manifest._git_commit()
    manifest._git_dirty()
    git = [argv for argv in commands if argv[0] == "git"]
    assert len(git) == 2
    assert all(argv[1] == "--no-optional-locks" for argv in git), git
