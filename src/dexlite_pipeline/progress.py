"""Progress lines with rate and ETA for long loops, written through ``logging``.

A line goes to the stage's logger (so to the terminal and to the job's log file alike) after
the first item, then at most every ``every_s`` seconds, and always after the last item:

    lift test: 24/96 grasps (25%), 1.9 grasps/s, elapsed 0:13, ETA 0:38

Items that need no work (an asset reused from an earlier run) are counted apart: they take no part
in the rate, and those still expected (``reusable``, known beforehand) none in the ETA, so a run that
starts with a thousand reused objects does not promise to end in seconds:

    preparation: 1130/1750 objects (65%; 1120 reused), 0.21 objects/s, elapsed 0:51, ETA 49:12

``advance`` may be called from several threads at once.
"""

from __future__ import annotations

import logging
import threading
import time

DEFAULT_EVERY_S = 10.0


def format_duration(seconds: float) -> str:
    """``H:MM:SS`` or ``M:SS``."""
    seconds = max(0, int(round(seconds)))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class ProgressLog:
    """Counts finished items of a known total and logs progress lines (see the module docstring)."""

    def __init__(self, logger: logging.Logger, label: str, total: int, unit: str = "items", every_s: float = DEFAULT_EVERY_S,
                 reusable: int = 0) -> None:
        self.logger, self.label, self.total, self.unit, self.every_s = logger, label, int(total), unit, float(every_s)
        self.reusable = int(reusable)  # items expected to need no work
        self.done = 0
        self.reused = 0
        self.started = time.perf_counter()
        self._last_line = -float("inf")
        self._lock = threading.Lock()

    def line(self) -> str:
        elapsed = time.perf_counter() - self.started
        worked = self.done - self.reused
        rate = worked / elapsed if elapsed > 0 else 0.0
        notes = [f"{100 * self.done / self.total:.0f}%"] if self.total else []
        if self.reused or self.reusable:
            notes.append(f"{self.reused} reused")
        share = f" ({'; '.join(notes)})" if notes else ""
        text = f"{self.label}: {self.done}/{self.total} {self.unit}{share}, {rate:.3g} {self.unit}/s, elapsed {format_duration(elapsed)}"
        to_work = self.total - self.done - max(0, self.reusable - self.reused)
        if 0 < self.done < self.total and to_work > 0 and rate > 0:
            text += f", ETA {format_duration(to_work / rate)}"
        return text

    def advance(self, count: int = 1, reused: bool = False) -> None:
        """Record ``count`` more finished items (``reused``: they needed no work); log a line when one is due."""
        with self._lock:
            self.done += int(count)
            if reused:
                self.reused += int(count)
            now = time.perf_counter()
            due = self.done >= self.total or self.done == count or now - self._last_line >= self.every_s
            if not due:
                return
            self._last_line = now
            text = self.line()
        self.logger.info("%s", text)
