"""Progress of a run on stderr: a live bar on a terminal, periodic plain lines in a batch log.

Both show trials done of total, ok/failed, the rate and the time left. The rate is the run's
average since it started (trials written ÷ wall time, as in the run's summary, which it equals
at the last trial), so it does not swing with the order in which workers finish.
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable, Iterator, TextIO

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, ProgressColumn, TextColumn
from rich.text import Text

LINE_INTERVAL_S = 30.0      # a batch log gets a line at most this often (and one at the end)


def trials_per_hour(done: int, seconds: float) -> float | None:
    """Average rate, trials/h (None before the first trial or the first instant)."""
    return done / seconds * 3600.0 if done and seconds > 0 else None


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds % 3600 // 60:02d}:{seconds % 60:02d}"


@dataclass
class Counts:
    """Trials of the run so far, and when it started (time.perf_counter(), s)."""

    total: int
    started: float
    done: int = 0
    failed: int = 0

    def rate(self, now: float) -> float | None:
        return trials_per_hour(self.done, now - self.started)

    def remaining_s(self, now: float) -> float | None:
        rate = self.rate(now)
        return (self.total - self.done) / rate * 3600.0 if rate else None

    def line(self, label: str, now: float) -> str:
        rate, left = self.rate(now), self.remaining_s(now)
        return (f"{label}: {self.done}/{self.total} trials done ({self.done - self.failed} ok, {self.failed} failed), "
                f"{f'{rate:,.0f}' if rate else '…'} trials/h, elapsed {_clock(now - self.started)}, "
                f"left {_clock(left) if left is not None else '…'}")


def _lines(counts: Counts, label: str, stream: TextIO, interval_s: float) -> Callable[[bool, float], None]:
    last = [time.perf_counter()]
    print(f"{label}: {counts.total} trials to run", file=stream, flush=True)

    def report(failed: bool, now: float) -> None:
        counts.done += 1
        counts.failed += failed
        if now - last[0] >= interval_s or counts.done == counts.total:
            last[0] = now
            print(counts.line(label, now), file=stream, flush=True)
    return report


@contextmanager
def _bar(counts: Counts, label: str) -> Iterator[Callable[[bool, float], None]]:
    class RateAndLeft(ProgressColumn):
        def render(self, task) -> Text:
            now = time.perf_counter()
            rate, left = counts.rate(now), counts.remaining_s(now)
            return Text(f"{f'{rate:,.0f}' if rate else '…'} trials/h  elapsed {_clock(now - counts.started)}  "
                        f"left {_clock(left) if left is not None else '…'}")

    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), RateAndLeft(),
                  console=Console(stderr=True)) as bar:
        task = bar.add_task(label, total=counts.total)

        def report(failed: bool, now: float) -> None:
            counts.done += 1
            counts.failed += failed
            bar.update(task, advance=1, description=f"{label} ({counts.failed} failed)" if counts.failed else label)
        yield report


@contextmanager
def progress(total: int, label: str, started: float, enabled: bool = True, stream: TextIO | None = None,
             interval_s: float = LINE_INTERVAL_S) -> Iterator[Callable[[bool, float], None]]:
    """Yields ``report(failed, now)``, called once per trial written (``now``: when, perf_counter
    s). A bar if ``stream`` (default stderr) is a terminal, else a line every ``interval_s`` and
    at the last trial; nothing if not ``enabled``. ``started``: the run's start (time.perf_counter(), s)."""
    stream = stream or sys.stderr
    counts = Counts(total, started)
    if not enabled:
        yield lambda failed, now: None
    elif stream.isatty():
        with _bar(counts, label) as report:
            yield report
    else:
        yield _lines(counts, label, stream, interval_s)
