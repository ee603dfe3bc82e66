"""The process and the machine while the harness measures: the lowest room, imported by all.

- ``timing``: frame-time medians with their intervals, and how much of the CPU other
  processes took while a run was timed (``cpu_contention``, ``noisy``).
- ``interrupt``: Ctrl-C and SIGTERM stop a command within a second, whatever library is running;
  long loops anywhere (mesh loading, the sweep) call ``raise_if_interrupted``.
- ``warnings_log``: library warnings caught as lines (a command's, a report worker's) and
  appended to the folder's ``warnings.log``, never printed.
- ``memory``: the process's resident memory, the peak of a stretch of work (what a sweep's
  batches are sized by) and the C heap's free pages given back.

Nothing here imports another part of the harness.
"""
