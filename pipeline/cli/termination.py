"""The process's signals: SIGTERM stops a command like Ctrl-C, and the exit code says so."""

from __future__ import annotations

import signal
import sys

import typer

TERMINATED_BY: list[str] = []      # the signal that stopped this process, if any


def terminate(signum, frame) -> None:
    """SIGTERM: stop like Ctrl-C (a run stops cleanly and says how to resume), then report it."""
    TERMINATED_BY.append(signal.Signals(signum).name)
    raise KeyboardInterrupt


def _interrupt_again(signum, frame) -> None:
    raise KeyboardInterrupt


def redeliver_swallowed_interrupt(hook_args) -> None:
    """A SIGTERM that landed inside a finalizer or weakref callback is swallowed there (Python
    prints it as an ignored exception, a traceback): deliver it again to the main code 10 ms
    later (SIGALRM), outside the callback, instead."""
    if isinstance(hook_args.exc_value, KeyboardInterrupt) and TERMINATED_BY:
        signal.signal(signal.SIGALRM, _interrupt_again)
        signal.setitimer(signal.ITIMER_REAL, 0.01)
        return
    sys.__unraisablehook__(hook_args)


def install() -> None:
    """Route SIGTERM and swallowed interrupts through this module."""
    signal.signal(signal.SIGTERM, terminate)
    sys.unraisablehook = redeliver_swallowed_interrupt


def exit_process(code: int) -> None:
    """Exit with ``code``, or with 128 + SIGTERM and an ``error:`` line if SIGTERM stopped the process."""
    if TERMINATED_BY:
        typer.echo(f"error: terminated by {TERMINATED_BY[0]}", err=True)
        sys.exit(128 + signal.SIGTERM)
    sys.exit(code)
