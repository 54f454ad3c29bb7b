"""docs/cluster.md's examples run: its batch-system YAML is a valid run config, and both ways it
shows to preview the job script (`pipeline job-script`, `job_script(...)` in Python) print the
script those options make."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from tests.conftest import run_pipeline

REPO = Path(__file__).resolve().parents[2]
PAGE = (REPO / "docs" / "cluster.md").read_text()


def blocks(language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", PAGE, flags=re.S | re.M)


def expected_lines(script: str) -> None:
    lines = script.splitlines()
    for line in ("#SBATCH -p compute", "#SBATCH -A my-lab", "#SBATCH -t 04:00:00", "#SBATCH --qos=normal",
                 "#SBATCH --cpus-per-task=16", "module load hdf5", "source ~/venvs/whisker/bin/activate"):
        assert line in lines, line
    worker = [line for line in lines if "dask_worker" in line]
    assert len(worker) == 1 and "tcp://SCHEDULER:8786" in worker[0] and "--interface ib0" in worker[0]
    assert "--nworkers 16" in worker[0] and "--nthreads 1" in worker[0]


def test_the_job_script_examples_of_docs_cluster_md_run(tmp_path):
    (tmp_path / "slurm.yaml").write_text(blocks("yaml")[0])
    preview = [b for b in blocks("bash") if "job-script" in b]
    assert preview == ["pipeline job-script --config slurm.yaml\n"]
    command = run_pipeline(*preview[0].split()[1:], cwd=tmp_path)
    assert command.returncode == 0, command.stderr
    expected_lines(command.stdout)
    snippet = [b for b in blocks("python") if "job_script" in b]
    assert len(snippet) == 1
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    python = subprocess.run([sys.executable, "-c", snippet[0]], cwd=tmp_path, env=env, capture_output=True,
                            text=True, timeout=120)
    assert python.returncode == 0, python.stderr
    assert python.stdout == command.stdout
    local = run_pipeline("job-script", cwd=tmp_path)                 # no batch kind: one error line
    assert local.returncode == 2 and local.stderr.startswith("error: cluster kind 'local' submits no batch jobs")
