"""What a long command is doing, on stderr, so a terminal or a batch log is never silent for
long. A command done within ``quiet_s`` prints nothing (a bad input, found up front, stays one
``error:`` line); after that, the current step, then a line when a step starts and every
``interval_s`` a line with the step's latest state and the time elapsed, and one at the end
with the total time.

    with Activity("trial") as activity:
        activity.step("simulating 30 whiskers for 0.06 s on bullet")
        ...                                   # long work: "trial: ... (elapsed 0:00:05)" lines
        activity.update("read 120/400 trials")   # shown on the next periodic line
"""

from __future__ import annotations

import sys
import threading
import time
from typing import TextIO

QUIET_S = 2.0             # nothing printed for a command done within this time
INTERVAL_S = 5.0          # then a line at least this often while a step runs


def clock(seconds: float) -> str:
    """``seconds`` as H:MM:SS."""
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds % 3600 // 60:02d}:{seconds % 60:02d}"


class Activity:
    """Progress lines of one command (``label: text``); ``enabled=False`` prints nothing (--json)."""

    def __init__(self, label: str, *, enabled: bool = True, quiet_s: float = QUIET_S,
                 interval_s: float = INTERVAL_S, stream: TextIO | None = None):
        self.label, self.enabled, self.quiet_s, self.interval_s = label, enabled, quiet_s, interval_s
        self.stream = stream or sys.stderr
        self.state = ""
        self.shown = quiet_s <= 0            # lines are printed (after quiet_s)
        self.started = time.perf_counter()
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None

    def _print(self, text: str) -> None:
        if self.enabled and self.shown:
            print(f"{self.label}: {text}", file=self.stream, flush=True)

    def step(self, text: str) -> None:
        """A new step: print it now (once ``quiet_s`` has passed)."""
        self.state = text
        self._print(text)

    def update(self, text: str) -> None:
        """The current step's latest state, printed with the next periodic line."""
        self.state = text

    def _tick(self) -> None:
        if not self.shown:
            if self._stop.wait(self.quiet_s):
                return
            self.shown = True
            self._print(self.state)
        while not self._stop.wait(self.interval_s):
            self._print(f"{self.state} (elapsed {clock(time.perf_counter() - self.started)})")

    def __enter__(self) -> "Activity":
        if self.enabled:
            self._ticker = threading.Thread(target=self._tick, name=f"activity-{self.label}", daemon=True)
            self._ticker.start()
        return self

    def __exit__(self, exc_type, *exc) -> None:
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
        if exc_type is None:
            self._print(f"done in {time.perf_counter() - self.started:.1f} s")
