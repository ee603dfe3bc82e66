"""What a finished scene's group freed goes back to the system before the next scene
(harness.run.measure.return_freed_memory, called by the serial sweep and on Dask workers).
In a fresh process whose glibc serves allocations below 32 MiB from the heap
(``MALLOC_MMAP_THRESHOLD_``: fixed, where glibc's own threshold moves with what was freed
before, which made the test fail now and then in the full suite), 400 arrays of 1 MiB come
from the heap; with every 50th kept, the freed ones stay resident until the heap is trimmed.
Catches return_freed_memory as a no-op (seen failing: 0 MiB returned; with it about 360 MiB),
which let a sweep grow from scene to scene (issue 34)."""

from __future__ import annotations

import os
import subprocess
import sys

SCRIPT = """
import numpy as np
from harness.run.measure import resident_bytes, return_freed_memory
arrays = [np.ones(2**20 // 8) for _ in range(400)]
kept = arrays[::50]
del arrays
before = resident_bytes()
return_freed_memory()
print((before - resident_bytes()) / 2**20)
"""


def test_freed_heap_pages_go_back_to_the_system():
    # the heap for every array here; freeing never trims it on its own (the top is kept)
    env = {**os.environ, "MALLOC_MMAP_THRESHOLD_": str(32 * 2**20),
           "MALLOC_TRIM_THRESHOLD_": str(2**40)}
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                          timeout=120, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    returned_mib = float(done.stdout.split()[-1])
    assert returned_mib > 200, returned_mib
