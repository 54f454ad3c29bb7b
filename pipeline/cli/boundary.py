"""The console entry point and the command line's one exception boundary."""

from __future__ import annotations

import errno
import os
import sys
import traceback

import typer

from pipeline.cli import termination
from pipeline.cli.app import app
from pipeline.cli.output import one_line
from pipeline.errors import SimulationError, UserError


# BLAS libraries that read these start one thread per core when loaded, and the extra threads spin
# for a while: ≈0.03–0.08 CPU-s at numpy's import on 2 cores, for nothing, since every fit and
# linear path here runs on ~100×100 matrices where one thread is faster (pipeline.diagnosis.threads).
# Set before any command imports numpy, unless the user set them; dask workers inherit them.
ONE_BLAS_THREAD = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def _click_errors() -> tuple[tuple[type, ...], tuple[type, ...], tuple[type, ...]]:
    """(usage errors, aborts, exits) of the click that typer runs: its bundled copy if it has one
    (then the installed click, ≈0.01 CPU-s to import, is not needed), else the installed click."""
    try:
        from typer._click.exceptions import ClickException
        return (ClickException,), (typer.Abort,), (typer.Exit,)
    except ImportError:          # typer versions that use the installed click
        import click
        return (click.ClickException,), (click.exceptions.Abort, typer.Abort), (click.exceptions.Exit, typer.Exit)


def main() -> None:
    """Console entry point and the CLI's one exception boundary.

    Usage errors (bad option value, unknown command or option, missing argument), a
    :class:`UserError` and an operating-system error on a named file (no space, permission)
    become one ``error:`` line and exit code 2; a :class:`SimulationError` exits 1; anything
    else is a bug and keeps its traceback. ``--debug`` shows the traceback of every error.
    """
    debug = "--debug" in sys.argv[1:]
    for name in ONE_BLAS_THREAD:
        os.environ.setdefault(name, "1")
    termination.install()
    usage_errors, aborts, exits = _click_errors()
    try:
        code = app(standalone_mode=False)
        termination.exit_process(code or 0)     # typer returns the code of an Exit/Abort (130 after Ctrl-C)
    except exits as exc:
        termination.exit_process(exc.exit_code)
    except usage_errors as exc:
        if type(exc).__name__ == "NoArgsIsHelpError":       # bare `pipeline` or group: help was asked for
            typer.echo(exc.ctx.get_help() if getattr(exc, "ctx", None) else str(exc))
            sys.exit(0)
        if debug:
            traceback.print_exc()
        typer.echo(f"error: {one_line(exc.format_message())} (see --help)", err=True)
        sys.exit(2)
    except (*aborts, KeyboardInterrupt):
        if not termination.TERMINATED_BY:
            typer.echo("interrupted", err=True)
        termination.exit_process(130)
    except UserError as exc:
        if debug:
            traceback.print_exc()
        typer.echo(f"error: {one_line(exc)}", err=True)
        sys.exit(2)
    except SimulationError as exc:
        if debug:
            traceback.print_exc()
        typer.echo(f"error: simulation failed: {one_line(exc)}", err=True)
        sys.exit(1)
    except OSError as exc:
        if exc.errno is None or (exc.filename is None and exc.errno not in (errno.ENOSPC, errno.EDQUOT)):
            raise
        if debug:
            traceback.print_exc()
        where = f": {exc.filename}" if exc.filename else ""
        typer.echo(f"error: {exc.strerror or one_line(exc)}{where}", err=True)
        sys.exit(2)
