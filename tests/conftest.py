"""Shared test fixtures: where ../shared lives (skip cleanly when it does not), the CLI as a user runs it;
the set-up cache of every test session (and the processes it starts) in a folder of its own."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"


@pytest.fixture(scope="session", autouse=True)
def session_setup_cache(tmp_path_factory):
    """Tests neither read nor fill the user's set-up cache (pipeline/model/setup_cache.py)."""
    before = os.environ.get("PIPELINE_CACHE_DIR")
    os.environ["PIPELINE_CACHE_DIR"] = str(tmp_path_factory.mktemp("setup-cache"))
    yield
    if before is None:
        del os.environ["PIPELINE_CACHE_DIR"]
    else:
        os.environ["PIPELINE_CACHE_DIR"] = before


@pytest.fixture
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip("../shared is not present")
    return SHARED


def run_pipeline(*args, cwd=REPO, timeout=600, env=None) -> subprocess.CompletedProcess:
    """``python -m pipeline.cli ARGS`` in a fresh process; text stdout/stderr captured."""
    return subprocess.run([sys.executable, "-m", "pipeline.cli", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, timeout=timeout, env=env)


@pytest.fixture
def pipeline_cli():
    """The ``pipeline`` command as a function: ``pipeline_cli("trial", "--json")``."""
    return run_pipeline
