"""Ctrl-C while finished runs are being stored (``interrupt.finishing``): the process waits
for the block to end rather than ending GRACE_S after the signal, says why, a second Ctrl-C
ends it at once, and so does HOLD_S."""

from __future__ import annotations

import subprocess

from helpers import PY, subprocess_env

from harness.machine import interrupt

STORING = """
import os, signal, sys, threading, time
from harness.machine import interrupt
interrupt.HOLD_S = {hold}
with interrupt.stop_on_signals():
    try:
        with interrupt.finishing():
            os.kill(os.getpid(), signal.SIGINT)
            if {again}:
                threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT)).start()
            time.sleep(2.5)  # storing what is done takes longer than GRACE_S
            open({marker!r}, "w").write("stored")
        interrupt.raise_if_interrupted()
    except KeyboardInterrupt:
        interrupt.announce()
        os._exit(interrupt.EXIT_CODE)
"""


def _storing(tmp_path, again: bool, hold: float = interrupt.HOLD_S):
    marker = tmp_path / "stored"
    proc = subprocess.run([PY, "-c", STORING.format(again=again, marker=str(marker), hold=hold)],
                          capture_output=True, text=True, timeout=60, env=subprocess_env())
    return proc, marker.exists()


def test_ctrl_c_waits_for_the_finished_runs_to_be_stored(tmp_path):
    """Catches a watcher that ends the process GRACE_S after the signal whatever the main
    thread is doing (the runs done but not yet stored would be lost), and a KeyboardInterrupt
    raised inside the block."""
    proc, stored = _storing(tmp_path, again=False)
    assert proc.returncode == interrupt.EXIT_CODE, proc.stderr
    assert stored
    assert proc.stderr.splitlines() == [interrupt.HOLDING, interrupt.MESSAGE]


def test_a_second_ctrl_c_stops_at_once(tmp_path):
    """Catches a wait that cannot be cut short."""
    proc, stored = _storing(tmp_path, again=True)
    assert proc.returncode == interrupt.EXIT_CODE, proc.stderr
    assert not stored  # ended 1 s into the block, not after it
    assert proc.stderr.splitlines()[-1] == interrupt.MESSAGE


def test_the_wait_ends_at_hold_s(tmp_path):
    """Catches a wait that a block which never ends would hold for ever."""
    proc, stored = _storing(tmp_path, again=False, hold=1.5)
    assert proc.returncode == interrupt.EXIT_CODE, proc.stderr
    assert not stored
    assert proc.stderr.splitlines() == [interrupt.HOLDING, interrupt.MESSAGE]
