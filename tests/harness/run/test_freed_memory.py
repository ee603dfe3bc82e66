"""What a finished scene's group freed goes back to the system before the next scene
(harness.run.measure.return_freed_memory, called by the serial sweep and on Dask workers).
In a fresh process: once glibc has raised its mmap threshold (a 16 MiB array freed), 400
arrays of 1 MiB come from the heap; with every 50th kept, the freed ones stay resident until
the heap is trimmed. Catches return_freed_memory as a no-op (seen failing: 0 MiB returned;
with it about 360 MiB), which let a sweep grow from scene to scene (issue 34)."""

from __future__ import annotations

import subprocess
import sys

SCRIPT = """
import numpy as np
from harness.run.measure import resident_bytes, return_freed_memory
big = np.ones(16 * 2**20 // 8)
del big
arrays = [np.ones(2**20 // 8) for _ in range(400)]
kept = arrays[::50]
del arrays
before = resident_bytes()
return_freed_memory()
print((before - resident_bytes()) / 2**20)
"""


def test_freed_heap_pages_go_back_to_the_system():
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    returned_mib = float(done.stdout.split()[-1])
    assert returned_mib > 200, returned_mib
