"""docs/python.md, the Python quick start: every snippet runs, in order and in one session, in
an empty project folder, and leaves what it says (a dataset, a plot, an NWB file)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def python_snippets(page: Path) -> list[str]:
    """The ```python blocks of a Markdown page, in order."""
    return re.findall(r"^```python\n(.*?)^```", page.read_text(), flags=re.S | re.M)


def test_every_snippet_of_the_python_quick_start_runs(tmp_path):
    snippets = python_snippets(REPO / "docs" / "python.md")
    assert len(snippets) == 6
    script = "\n".join(f"print('--- snippet {i}', flush=True)\n{code}" for i, code in enumerate(snippets))
    env = {**os.environ, "PIPELINE_HOME": str(tmp_path), "MPLBACKEND": "Agg",
           "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-3000:]
    assert "['RC1', 'RC2'] (50,) (50, 2, 6)" in run.stdout
    assert re.search(r"^4 2 ", run.stdout, flags=re.M)            # DataTree tables: 4 trials, 2 whiskers
    assert "4 trials ok" in run.stdout and "4 trials" in run.stdout.splitlines()[-1]
    assert (tmp_path / "outputs" / "datasets" / "quickstart" / "v1" / "manifest.json").is_file()
    assert (tmp_path / "rc1_mz.png").stat().st_size > 1000 and (tmp_path / "quickstart.nwb").is_file()
