"""What a long command writes where (issue 47, friction 2): progress on stderr, as plain lines
in a log and as a bar on a terminal, the summary on stdout, ``--quiet`` and ``--verbose``, and
the Ctrl-C message on a line of its own in both. Each test names the broken code it catches."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import struct
import subprocess
import termios
import time

import yaml
from helpers import GOOD, PY, subprocess_env, write_scenes

from harness import cli
from harness.machine import interrupt


def _experiment(tmp_path, out="out"):
    """Two scenes (32x32) of sm and pcf, one frame each: 4 runs."""
    scene_file = write_scenes(tmp_path, {"a": GOOD, "b": GOOD})
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({"techniques": {"sm": None, "pcf": None}, "frames": 1,
                                          "warmup": 0, "reference": {"samples": 1}}))
    return ["run", str(experiment), "--scene-file", str(scene_file), "--out", str(tmp_path / out)]


def test_in_a_log_progress_is_plain_lines_and_the_summary_goes_to_stdout(tmp_path, gl_context):
    """``shadowbench run ... > out 2> err``, stderr not a terminal: a line as each scene
    begins and count lines, no carriage return; the summary on stdout alone. Catches the tqdm
    bar written into a log (before: stderr one line of \\r-joined redraws, the summary at its
    end, stdout empty)."""
    proc = subprocess.run([PY, "-m", "harness.cli", *_experiment(tmp_path)], capture_output=True,
                          text=True, timeout=300, env=subprocess_env())
    assert proc.returncode == 0, proc.stderr
    assert "\r" not in proc.stderr
    err = proc.stderr.splitlines()
    assert [line.split(" (")[0] for line in err if " runs (" in line] == ["a 32x32: 2 runs",
                                                                        "b 32x32: 2 runs"]
    assert any(line.startswith("4/4 runs done, 0 to go") for line in err), err
    summary = proc.stdout.splitlines()
    assert re.fullmatch(r"4 runs in .*/results\.csv \(4 ok, 0 skipped, 0 failed; 4 rendered now, "
                        r"0 already done\) in [\d.]+ s", summary[0]), summary
    assert summary[-1].startswith("the report: shadowbench report ")
    assert not [line for line in err if "results.csv" in line or "the report" in line]


def test_quiet_shows_no_progress_and_verbose_a_line_per_run(tmp_path, gl_context, capsys):
    """Catches: --quiet that still prints (or prints no summary), and no --verbose (before:
    argparse refused it)."""
    assert cli.main(_experiment(tmp_path) + ["--quiet"]) == 0
    quiet = capsys.readouterr()
    assert not [line for line in quiet.err.splitlines() if not line.startswith("warning: ")]
    assert "4 runs in" in quiet.out
    assert cli.main(_experiment(tmp_path, "verbose") + ["--verbose"]) == 0
    verbose = capsys.readouterr()
    runs = [line for line in verbose.err.splitlines()
            if re.fullmatch(r"[ab] 32x32 (sm|pcf): [\d.e+-]+ ms \[[1-4]/4\]", line)]
    assert len(runs) == 4, verbose.err
    assert "4 rendered now" in verbose.out


def test_reference_and_report_show_progress_and_print_their_result_on_stdout(tmp_path, gl_context,
                                                                           capsys):
    """The other long commands use the same progress. Catches a command left silent until it
    ends (before: reference and report said nothing while they worked)."""
    args = _experiment(tmp_path)
    out = tmp_path / "out"
    assert cli.main(args + ["--quiet"]) == 0
    capsys.readouterr()
    assert cli.main(["reference", "--scene", "a", "--scene-file", str(tmp_path / "scenes.yaml"),
                     "--samples", "1", "--out", str(tmp_path / "ref")]) == 0
    made = capsys.readouterr()
    assert made.err.splitlines()[0].startswith("a 32x32: 1 samples (0/1 references done")
    assert made.err.splitlines()[-1].startswith("1/1 references done")
    assert made.out.startswith(str(tmp_path / "ref" / "arrays" / "a"))
    assert cli.main(["report", str(out)]) == 0
    built = capsys.readouterr()
    assert "images of 2 scenes" in built.err.splitlines()[0]
    assert built.err.splitlines()[-1].startswith("2/2 scenes done")
    assert built.out.strip().endswith("index.html")
    assert cli.main(["report", str(out), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


# A reference that never lets go of Ctrl-C: the watcher ends the process while the progress
# shows the scene's reference (on a terminal, a bar whose line is still open)
STUBBORN = """
import os, signal, sys, threading, time
import harness.truth.reference as r
from harness import cli
def stubborn(*a, **k):
    threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
    while True:
        try:
            time.sleep(0.01)
        except BaseException:
            pass
r.compute_reference = stubborn
sys.argv[1:] = {args!r}
sys.exit(cli.main())
"""


def test_the_ctrl_c_message_has_its_own_line_in_a_log(tmp_path):
    """Catches the message glued to the bar's last redraw (before, in make bench's log:
    '...| 00:18 elapsedshadowbench: interrupted; ...')."""
    proc = subprocess.run([PY, "-c", STUBBORN.format(args=_experiment(tmp_path))],
                          capture_output=True, text=True, timeout=120, env=subprocess_env())
    assert proc.returncode == interrupt.EXIT_CODE, proc.stderr
    assert "\r" not in proc.stderr
    assert proc.stderr.splitlines()[-1] == interrupt.MESSAGE, proc.stderr


def test_the_ctrl_c_message_has_its_own_line_on_a_terminal(tmp_path):
    """On a terminal the bar is drawn in place, its line open: the message starts a new line
    below it. Catches an announcement that does not know of the bar (before: 'elapsed'
    followed by 'shadowbench: interrupted' on one line)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 160, 0, 0))
    proc = subprocess.Popen([PY, "-c", STUBBORN.format(args=_experiment(tmp_path))],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave,
                            env=subprocess_env())
    os.close(slave)
    shown, deadline = b"", time.monotonic() + 120
    try:
        while time.monotonic() < deadline:
            if not select.select([master], [], [], 1)[0]:
                continue
            try:
                chunk = os.read(master, 4096)
            except OSError:  # EIO: the child closed the terminal
                break
            if not chunk:
                break
            shown += chunk
    finally:
        os.close(master)
        proc.kill()
        proc.wait()
    text = shown.decode()
    assert "runs done" in text and "\r" in text, text  # the bar, redrawn in place
    before = text[:text.index(interrupt.MESSAGE)]
    assert before.endswith("\n"), repr(text[-300:])
