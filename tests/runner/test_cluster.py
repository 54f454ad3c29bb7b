"""Cluster kinds (issue 18 §3): the batch systems through dask-jobqueue, checked with stand-in
sbatch/squeue/scancel that run the generated job script on this machine; the job-array example;
HTTP servers on the loopback only; progress lines in batch logs."""

from __future__ import annotations

import io
import json
import os
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path

import dask
import psutil
import pytest

from tests.conftest import REPO, run_pipeline
from pipeline.config.simulate import ClusterConfig, load_simulate_config
from pipeline.datasets import manifest
from pipeline.errors import UserError
from pipeline.runner.cluster import SERVER_CLOCKS, dask_client, job_script
from pipeline.runner.progress import progress, trials_per_hour
from test_location import make_project, user_env

STANDIN_SLURM = Path(__file__).parents[1] / "standin_slurm"


def test_batch_options_are_validated(tmp_path):
    def load(cluster: dict):
        path = tmp_path / "c.yaml"
        path.write_text(json.dumps({"cluster": cluster}))
        return load_simulate_config(path).cluster

    assert load({"scheduler": "tcp://10.0.0.1:8786"}).kind == "scheduler"
    # a batch config run locally (--workers, as a job-array task does): its batch options are not used
    path = tmp_path / "c.yaml"
    path.write_text(json.dumps({"cluster": {"kind": "slurm", "cores": 4, "memory": "8GB", "queue": "short"}}))
    assert load_simulate_config(path, {"cluster": {"kind": "local", "workers": 2}}).cluster.kind == "local"
    slurm = load({"kind": "slurm", "cores": 4, "memory": "8GB", "account": "lab"})
    assert slurm.batch_options() == {"cores": 4, "memory": "8GB", "account": "lab", "processes": 4}
    assert load({"kind": "sge", "cores": 2, "memory": "2GB", "account": "lab"}).batch_options()["project"] == "lab"
    for cluster, message in (({"kind": "slurm", "cores": 4}, "needs 'cores' and 'memory'"),
                             ({"kind": "slurm", "cores": 4, "memory": "lots"}, "amount of memory"),
                             ({"kind": "scheduler"}, "needs 'scheduler: tcp://HOST:PORT'"),
                             ({"kind": "pbs", "cores": 1, "memory": "1GB", "walltime": "1 hour"}, "walltime"),
                             ({"kind": "condor"}, "kind")):
        with pytest.raises(UserError, match=message):
            load(cluster)


def test_slurm_job_script_carries_the_options():
    config = ClusterConfig(kind="slurm", cores=3, memory="6GB", walltime="02:00:00", queue="short", account="lab",
                           job_extra_directives=["--qos=normal"], job_script_prologue=["module load hdf5"])
    script = job_script(config)
    for line in ("#SBATCH -p short", "#SBATCH -A lab", "#SBATCH -t 02:00:00", "#SBATCH --qos=normal",
                 "#SBATCH -n 1", "#SBATCH --cpus-per-task=3", "module load hdf5"):
        assert line in script.splitlines(), line
    worker = script.splitlines()[-1]
    assert worker.startswith(f"{sys.executable} -m distributed.cli.dask_worker tcp://")
    assert "--nthreads 1" in worker and "--nworkers 3" in worker       # single-threaded workers
    assert "--dashboard-address 127.0.0.1:0" in worker


def test_ctrl_c_still_interrupts_after_a_batch_cluster_class_is_loaded():
    # dask-jobqueue 0.9.0 swaps SIGINT's handler for a silent exit 0 when imported (issue #696)
    # (the handler before any import: Python's, or SIG_IGN in a background job such as CI's)
    code = ("import signal; before = signal.getsignal(signal.SIGINT); import pipeline.cli.app; "
            "from pipeline.config.simulate import ClusterConfig; from pipeline.runner.cluster import job_script; "
            "job_script(ClusterConfig(kind='slurm', cores=1, memory='1GB')); "
            "print(signal.getsignal(signal.SIGINT) is before)")
    result = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "True"


def test_a_batch_kind_without_its_submit_command_is_one_error(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))          # no sbatch here
    with pytest.raises(UserError, match="cluster kind 'slurm': `sbatch` not found on PATH"):
        with dask_client(ClusterConfig(kind="slurm", cores=1, memory="1GB")):
            pass


def _listening(pids: set[int]) -> set[str]:
    return {c.laddr.ip for c in psutil.net_connections("inet")
            if c.status == psutil.CONN_LISTEN and c.pid in pids}


def test_local_cluster_listens_on_loopback_only_and_never_warns_about_port_8787(capsys):
    with socket.socket() as taken:
        try:                             # 8787 in use, as when another dask cluster runs
            taken.bind(("127.0.0.1", 8787))
            taken.listen()
        except OSError:
            pass
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with dask_client(ClusterConfig(workers=1)) as client:
                me = psutil.Process()
                ips = _listening({me.pid} | {p.pid for p in me.children(recursive=True)})
                status_server = client.cluster.scheduler.http_server          # always on, dashboard or not
                assert status_server.address == "127.0.0.1" and status_server.port != 8787
        assert not [w for w in caught if "already in use" in str(w.message)]
    assert ips and ips <= {"127.0.0.1"}, ips
    assert "dashboard" not in capsys.readouterr().err
    with dask_client(ClusterConfig(workers=1, dashboard=True, dashboard_port=0)):
        pass
    shown = capsys.readouterr().err
    assert shown.startswith("dask dashboard: http://127.0.0.1:") and "ssh -L" in shown


def _profiling(dask_worker) -> bool:
    return dask_worker.periodic_callbacks.get("profile") is not None


def test_local_workers_run_without_dasks_profiler():
    """Its call trees grew a worker by ≈ 25 MB per 100 trials (docs/scaling.md, issue 26, session 22)."""
    with dask_client(ClusterConfig(workers=1)) as client:
        assert list(client.run(_profiling).values()) == [False]


def test_a_local_clusters_servers_wake_at_the_run_clocks_and_the_callers_config_is_untouched():
    before = {key: dask.config.get(key) for key in SERVER_CLOCKS}
    assert before != SERVER_CLOCKS                     # dask's own 20 ms and 500 ms
    expected = (1.0, 5.0)
    assert tuple(dask.utils.parse_timedelta(SERVER_CLOCKS[k]) for k in SERVER_CLOCKS) == expected
    with dask_client(ClusterConfig(workers=1)) as client:
        def clocks(dask_scheduler=None, dask_worker=None) -> tuple[float, float]:   # tick, monitor; s
            server = dask_scheduler or dask_worker
            return server._tick_interval, server.periodic_callbacks["monitor"].callback_time / 1000
        assert client.run_on_scheduler(clocks) == expected
        assert list(client.run(clocks).values()) == [expected]
        assert [clocks(dask_worker=nanny) for nanny in client.cluster.workers.values()] == [expected]
    assert {key: dask.config.get(key) for key in SERVER_CLOCKS} == before


def test_plain_progress_lines_agree_with_the_summary_rate():
    stream = io.StringIO()
    started = time.perf_counter() - 10.0
    with progress(3, "ref/v1", started, stream=stream, interval_s=3600.0) as report:
        for i, failed in enumerate((False, True, False)):
            report(failed, started + 10.0 * (i + 2))
    lines = stream.getvalue().splitlines()
    assert lines == ["ref/v1: 3 trials to run",
                     f"ref/v1: 3/3 trials done (2 ok, 1 failed), {trials_per_hour(3, 40.0):,.0f} trials/h, "
                     "elapsed 0:00:40, left 0:00:00"]


def _cancel_leftover_jobs(jobs: Path) -> None:
    for job in jobs.glob("*.job"):
        subprocess.run([STANDIN_SLURM / "scancel", job.stem], env={**os.environ, "STANDIN_SLURM_DIR": str(jobs)})


def test_slurm_cluster_completes_a_dataset_with_standin_commands(tmp_path):
    """`cluster: {kind: slurm}` submits a worker job with sbatch (here: run locally), runs the
    trials on it, and cancels it at the end; the batch log gets plain progress lines."""
    home = make_project(tmp_path, trials=4, kind="slurm", cores=2, memory="2GB", walltime="00:10:00",
                        worker_wait_s=120)
    jobs = tmp_path / "jobs"
    env = {**user_env(home), "PATH": f"{STANDIN_SLURM}{os.pathsep}{os.environ['PATH']}",
           "STANDIN_SLURM_DIR": str(jobs)}
    try:
        result = run_pipeline("simulate", "--json", cwd=tmp_path, env=env, timeout=400)
        assert result.returncode == 0, result.stderr
        summary = json.loads(result.stdout)
        assert summary["complete"] and summary["ok"] + summary["failed"] == 4 and summary["ok"] >= 2
        assert manifest.verify(Path(summary["dataset"])) == []
        submitted = list(jobs.glob("*.job"))
        assert len(submitted) == 1
        script = Path(submitted[0].read_text().strip()).read_text()
        assert "#SBATCH --cpus-per-task=2" in script and "#SBATCH -t 00:10:00" in script
        for _ in range(50):              # scancel ends the job when the run closes its cluster
            if subprocess.run([STANDIN_SLURM / "squeue"], env=env, capture_output=True,
                              text=True).stdout.splitlines()[1:] == []:
                break
            time.sleep(0.2)
        else:
            pytest.fail("the worker job is still running after the run")
    finally:
        _cancel_leftover_jobs(jobs)


@pytest.mark.slow
def test_job_array_example_shards_then_joins(tmp_path):
    """examples/slurm: two array tasks run as SLURM would start them (concurrently, with the
    array variables set; the project's config is written for `kind: slurm`, each task runs its
    shard on a local cluster), `datasets list` shows the shards ready to join, join.sbatch joins."""
    home = make_project(tmp_path, trials=4, kind="slurm", cores=2, memory="2GB")
    examples = REPO / "examples" / "slurm"
    env = {**user_env(home), "PIPELINE": f"{sys.executable} -m pipeline.cli", "DATASET": "ref",
           "SLURM_ARRAY_TASK_COUNT": "2", "SLURM_CPUS_PER_TASK": "1"}
    tasks = [subprocess.Popen(["bash", examples / "simulate_array.sbatch"], cwd=tmp_path, text=True,
                              env={**env, "SLURM_ARRAY_TASK_ID": str(i)}, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE) for i in (1, 2)]
    for task in tasks:
        out, err = task.communicate(timeout=400)
        assert task.returncode == 0, err
        assert "trials done" in err               # a batch log: plain progress lines, no bar
    rows = json.loads(run_pipeline("datasets", "list", "--json", cwd=tmp_path, env=env).stdout)
    assert len(rows) == 1 and rows[0]["state"] == "ready to join"
    assert (rows[0]["shards_done"], rows[0]["shards"], rows[0]["trials"], rows[0]["pending"]) == (2, 2, 4, 0)
    joined = subprocess.run(["bash", examples / "join.sbatch"], cwd=tmp_path, env=env, capture_output=True,
                            text=True, timeout=120)
    assert joined.returncode == 0, joined.stderr
    version = home / "outputs" / "datasets" / "ref" / "v1"
    assert manifest.verify(version) == [] and len(list((version / "meshes").glob("*.obj"))) == 1
    rows = json.loads(run_pipeline("datasets", "list", "--json", cwd=tmp_path, env=env).stdout)
    assert [(r["dataset"], r["state"], r["trials"]) for r in rows] == [("ref/v1", "complete", 4)]
