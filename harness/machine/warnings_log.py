"""Library warnings kept off the terminal: what a command's process (and the report's worker
processes) warn or log at WARNING level is caught as lines (:class:`Caught`) and appended to
``DIR/warnings.log`` of the folder the command works on (:func:`append`).

A warning about one run's numbers goes into that run's ``warnings`` column instead
(``harness.run.score``); this is for the rest: trimesh, scikit-image, NumPy, pandas, Mitsuba.
"""

from __future__ import annotations

import logging
import time
import warnings
from pathlib import Path

WARNINGS_LOG = "warnings.log"


class _LogRecords(logging.Handler):
    """Warnings that libraries log (trimesh logs rather than warns) kept as lines, in place of
    logging's last resort, which prints them on stderr."""

    def __init__(self, lines: list[str]):
        super().__init__(logging.WARNING)
        self.lines = lines

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(f"{record.levelname} {record.name}: "
                          f"{' '.join(record.getMessage().split())}")


def warning_line(w: warnings.WarningMessage) -> str:
    """One line: the category, the file's name and line, the message on one line."""
    return (f"{w.category.__name__} {Path(w.filename).name}:{w.lineno}: "
            f"{' '.join(str(w.message).split())}")


class Caught:
    """``with Caught() as caught:`` every warning raised (each once per place, as Python's
    ``default`` action shows them) and every record logged at WARNING or above inside the block
    is kept in ``caught.lines`` rather than printed. Not for threads: Python's warning filters
    are the process's."""

    def __init__(self):
        self.lines: list[str] = []
        self._handler = _LogRecords(self.lines)
        self._recording = warnings.catch_warnings(record=True)
        self._warnings: list[warnings.WarningMessage] = []

    def __enter__(self) -> "Caught":
        self._warnings = self._recording.__enter__()
        warnings.simplefilter("default")
        logging.getLogger().addHandler(self._handler)
        return self

    def __exit__(self, *exc) -> None:
        logging.getLogger().removeHandler(self._handler)
        self._recording.__exit__(*exc)
        self.lines[:0] = [warning_line(w) for w in self._warnings]


def append(folder: str | Path | None, lines: list[str]) -> None:
    """Append ``lines`` to ``folder``/warnings.log, each stamped with the time; nothing without
    lines or without the folder (they are dropped: never onto the terminal)."""
    if not lines or folder is None or not Path(folder).is_dir():
        return
    stamp = time.strftime("%Y-%m-%dT%H:%M:%S")
    with open(Path(folder) / WARNINGS_LOG, "a", encoding="utf-8") as log:
        log.writelines(f"{stamp} {line}\n" for line in lines)
