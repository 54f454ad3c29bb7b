"""Open a trial recording in the rerun viewer (native window or web viewer on 127.0.0.1).

A target is an ``.rrd`` file or a dataset ``NAME[/vK]`` whose version folder holds
``recordings/trial_<index:06d>.rrd``; ``NAME`` alone means its newest version.

The ``rerun`` command is a Python wrapper that starts the viewer binary as a child; killing the
wrapper alone leaves the viewer running, so it is started in its own process group and the
whole group is stopped on exit (rerun's own ``rr.spawn`` returns no handle to stop the viewer it
starts); psutil tells when no live process of the group is left.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from pipeline.datasets.versions import version_folder
import psutil

from pipeline.errors import UserError

RECORDINGS_DIR = "recordings"
HOST = "127.0.0.1"
DEFAULT_WEB_PORT = 9090
_TRIAL = re.compile(r"^trial_(\d{6})\.rrd$")


def recording_name(trial: int) -> str:
    return f"trial_{trial:06d}.rrd"


def recorded_trials(version_dir: Path) -> list[int]:
    """Trial indices with a (complete, renamed) recording in a dataset version folder."""
    folder = version_dir / RECORDINGS_DIR
    if not folder.is_dir():
        return []
    return sorted(int(m.group(1)) for p in folder.iterdir() if (m := _TRIAL.match(p.name)))


def _ranges(indices: list[int]) -> str:
    """[0, 1, 2, 5, 7, 8] → '0-2, 5, 7-8'."""
    parts, start = [], None
    for i, value in enumerate(indices):
        if start is None:
            start = value
        if i + 1 == len(indices) or indices[i + 1] != value + 1:
            parts.append(str(start) if start == value else f"{start}-{value}")
            start = None
    return ", ".join(parts)


def resolve_target(target: str, trial: int | None = None, root: Path | None = None) -> Path:
    """The ``.rrd`` file a ``pipeline view`` target names; UserError if it does not exist."""
    if target.endswith(".rrd") or Path(target).is_file():
        path = Path(target)
        if not path.is_file():
            raise UserError(f"recording not found: {path}")
        if trial is not None:
            raise UserError("--trial applies to dataset targets (NAME[/vK]), not to an .rrd file")
        return path

    folder = version_folder(target, root)
    label = f"{folder.parent.name}/{folder.name}"
    trials = recorded_trials(folder)
    listing = (f"trials with recordings: {_ranges(trials)}" if trials
               else "no trial of this version has a recording")
    if trial is None:
        raise UserError(f"give --trial I for dataset '{label}'; {listing}")
    path = folder / RECORDINGS_DIR / recording_name(trial)
    if not path.is_file():
        raise UserError(f"dataset '{label}' has no recording of trial {trial}; {listing}")
    return path


def _rerun_executable() -> str:
    beside = Path(sys.executable).parent / "rerun"
    if beside.is_file():
        return str(beside)
    found = shutil.which("rerun")
    if not found:
        raise UserError("the 'rerun' command was not found: install rerun-sdk (make install)")
    return found


VERIFY_TIMEOUT_S = 60.0


def check_recording(path: Path) -> None:
    """UserError unless rerun can load ``path`` entirely (``rerun rrd verify``, bounded in time):
    a corrupt recording must not open as an empty viewer."""
    try:
        result = subprocess.run([_rerun_executable(), "rrd", "verify", str(path)], capture_output=True,
                                text=True, timeout=VERIFY_TIMEOUT_S, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise UserError(f"{path}: rerun could not check the recording within {VERIFY_TIMEOUT_S:g} s") from None
    if result.returncode != 0:
        lines = [line for line in (result.stderr + result.stdout).splitlines() if line.strip()]
        reason = " ".join(lines[0].split())[:200] if lines else f"exit code {result.returncode}"
        raise UserError(f"{path}: not a valid rerun recording ({reason})")


def _check_port(port: int) -> None:
    with socket.socket() as s:
        try:
            s.bind((HOST, port))
        except OSError:
            raise UserError(f"port {port} on {HOST} is in use: choose another with --port") from None


@dataclass
class ViewerProcess:
    """A running viewer; ``stop()`` ends the wrapper and the viewer it started."""

    process: subprocess.Popen
    url: str | None = None

    def stop(self, timeout_s: float = 5.0) -> None:
        """SIGTERM the viewer's process group, SIGKILL what is left after ``timeout_s``."""
        for sig in (signal.SIGTERM, signal.SIGKILL):
            if not self._group_alive():
                break
            try:
                os.killpg(self.process.pid, sig)
            except ProcessLookupError:
                break
            deadline = time.monotonic() + timeout_s
            while self._group_alive() and time.monotonic() < deadline:
                time.sleep(0.05)

    def _group_alive(self) -> bool:
        """Any live (non-zombie) process left in the viewer's process group?"""
        self.process.poll()                       # reap the wrapper so it does not linger
        return _group_has_live_process(self.process.pid)

    def __enter__(self) -> "ViewerProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def _group_has_live_process(pgid: int) -> bool:
    """Any process of group ``pgid`` that is not a zombie (psutil's process table)."""
    for proc in psutil.process_iter(["status"]):
        try:
            if os.getpgid(proc.pid) == pgid and proc.info["status"] not in (psutil.STATUS_ZOMBIE,
                                                                            psutil.STATUS_DEAD):
                return True
        except (ProcessLookupError, PermissionError):         # gone, or not ours to look at
            continue
    return False


def web_url(web_port: int, grpc_port: int) -> str:
    return f"http://{HOST}:{web_port}/?url=rerun%2Bhttp%3A%2F%2F{HOST}%3A{grpc_port}%2Fproxy"


def start_viewer(path: Path, web: bool = False, port: int | None = None,
                 quiet: bool = False) -> ViewerProcess:
    """Start ``rerun`` on ``path`` bound to 127.0.0.1; ``port``: web page port (``--web``, data
    is then served on ``port + 1``) or the native viewer's server port. Returns at once; the web
    viewer may need a moment to listen."""
    command = [_rerun_executable(), "--bind", HOST]
    url = None
    if web:
        web_port = DEFAULT_WEB_PORT if port is None else port
        grpc_port = web_port + 1                  # fixed pair: easy to forward over ssh
        _check_port(web_port)
        _check_port(grpc_port)
        command += ["--web-viewer", "--web-viewer-port", str(web_port), "--port", str(grpc_port)]
        url = web_url(web_port, grpc_port)
    else:
        if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                     or os.environ.get("WAYLAND_DISPLAY")):
            raise UserError("no display for the native viewer: use --web and open the printed URL")
        if port is not None:
            _check_port(port)
            command += ["--port", str(port)]
    command.append(str(path))
    output = subprocess.DEVNULL if quiet else None
    process = subprocess.Popen(command, start_new_session=True, stdin=subprocess.DEVNULL,
                               stdout=output, stderr=output)
    return ViewerProcess(process, url)


def wait_listening(viewer: ViewerProcess, port: int, timeout_s: float = 15.0) -> None:
    """Block until the viewer accepts connections on ``port``; UserError if it exits first."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if viewer.process.poll() is not None:
            raise UserError(f"the rerun viewer exited with code {viewer.process.returncode} "
                            "(see its messages above)")
        try:
            with socket.create_connection((HOST, port), timeout=0.5):
                return
        except OSError:
            time.sleep(0.2)
    raise UserError(f"the rerun viewer did not listen on {HOST}:{port} within {timeout_s:.0f} s")


def view(path: Path, web: bool = False, port: int | None = None,
         announce: Callable[[dict], None] = print) -> int:
    """Show ``path`` until the viewer is closed or Ctrl-C / SIGTERM; always stops the viewer.
    ``announce`` gets {file, url (web only, else None), host, ports} once the viewer is up."""
    check_recording(path)
    viewer = start_viewer(path, web=web, port=port)
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        where = {"file": str(path), "url": None, "host": HOST, "ports": []}
        if web:
            web_port = DEFAULT_WEB_PORT if port is None else port
            wait_listening(viewer, web_port)
            where.update(url=viewer.url, ports=[web_port, web_port + 1])
        announce(where)
        return viewer.process.wait()
    finally:
        viewer.stop()
        signal.signal(signal.SIGTERM, previous)


def _raise_interrupt(signum, frame):
    raise KeyboardInterrupt
