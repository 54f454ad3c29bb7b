"""Property-based fuzzing (Hypothesis) of the command line (issue 28).

Invariant: ``pipeline ARGS`` exits 0, or exits 2 with exactly one line on stderr starting
``error:``; never another exception (which :func:`pipeline.cli.main` lets through as a traceback).
Commands run in-process through ``main()`` itself (so its mapping of errors to exit codes is what
is tested), each with ``sys.argv``, stdout, stderr, the working folder, ``PIPELINE_HOME``, the
SIGTERM handler and ``sys.unraisablehook`` set for it and restored after it: ``main()`` installs
the last two process-wide, and click binds its streams when a command starts, so a harness that
left them in place leaked one invocation's state into the next. Argument lists are drawn so that a
valid one is cheap (one whisker, a few ms); CI runs ``FUZZ_EXAMPLES`` per command, ``make test-all``
``FUZZ_EXAMPLES_SLOW``.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import signal
import sys
from pathlib import Path

import pytest

pytest.importorskip("hypothesis")
from hypothesis import strategies as st  # noqa: E402
from hypothesis import given  # noqa: E402

from test_fuzz_parsers import FAST, SLOW, budget  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / "data"

numbers = st.one_of(st.sampled_from(["0", "-1", "nan", "inf", "-inf", "1e308", "1e-300", "1e999", "0x10", "", " ",
                                     "1,2", "--json", "١", "9" * 40]),
                    st.floats().map(repr), st.integers(-10**20, 10**20).map(str), st.text(max_size=6))
texts = st.one_of(st.sampled_from(["", ",", "all", "R", "RC1", "RC1,,RC1", "mesh:", "mesh:/dev/null", "../..", "-",
                                   "\x00", "é", "--help"]), st.text(max_size=10))


def _positive_int(text: str) -> bool:
    try:
        return int(text) > 0
    except ValueError:
        return False


def options(**choices):
    """Argument lists: some of the options ``choices`` (name: strategy of its value), in any order."""
    pair = st.sampled_from(sorted(choices)).flatmap(lambda name: choices[name].map(lambda value: [name, value]))
    return st.lists(pair, max_size=4).map(lambda pairs: [token for p in pairs for token in p])


def command(prefix: list[str], strategy, fixed: list[str] = ()):
    return strategy.map(lambda args: [*prefix, *fixed, *args])


CHEAP_TRIAL = ["--whiskers", "RC1", "--duration-s", "0.002"]
COMMANDS = {
    "info": command(["info"], options(**{"--configs": texts, "--json": st.just("--json")})),
    "datasets-list": command(["datasets", "list"], options(**{"--root": texts})),
    "datasets-show": command(["datasets", "show"], st.lists(texts, max_size=3)),
    "resonance": command(["resonance"], options(**{"--length-mm": numbers, "--base-diameter-um": numbers,
                                                    "--tip-diameter-um": numbers, "--zeta": numbers,
                                                    "--E-gpa": numbers, "--links": numbers, "--dt-s": numbers,
                                                    "--curvature-per-mm": numbers, "--modes": numbers,
                                                    "--follicle": texts, "--whisker": texts})),
    "trial": command(["trial"], options(**{"--pose": texts | numbers, "--whiskers": texts, "--duration-s": numbers,
                                           "--scene": texts}), CHEAP_TRIAL),
    "simulate": command(["simulate", "--config", "run.yaml"], options(**{"--n": numbers.filter(lambda t: not _positive_int(t)), "--seed": numbers,
                                                                        "--shard": texts | numbers}),
                        ["--n", "0"]),
    "export": command(["export", "whiskit", "data.h5", "--out", "whiskit-out"],
                      options(**{"--trial": numbers})),
    "stats": command(["stats"], st.lists(texts, max_size=2)),
}


@contextlib.contextmanager
def isolated(folder: Path):
    """The process-wide state one ``main()`` call sets or reads, set for it and restored after."""
    saved = (sys.argv, os.getcwd(), os.environ.get("PIPELINE_HOME"), signal.getsignal(signal.SIGTERM),
             sys.unraisablehook)
    os.chdir(folder)
    os.environ["PIPELINE_HOME"] = str(folder)
    try:
        yield
    finally:
        sys.argv, cwd, home, handler, sys.unraisablehook = saved
        os.chdir(cwd)
        if home is None:
            os.environ.pop("PIPELINE_HOME", None)
        else:
            os.environ["PIPELINE_HOME"] = home
        signal.signal(signal.SIGTERM, handler)


def run_main(args: list[str], folder: Path) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of ``pipeline ARGS`` run in-process."""
    from pipeline.cli import main

    out, err = io.StringIO(), io.StringIO()
    with isolated(folder), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        sys.argv = ["pipeline", *args]
        try:
            main()
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    return code, out.getvalue(), err.getvalue()


def holds(args: list[str], folder: Path) -> None:
    code, out, err = run_main(args, folder)
    lines = err.splitlines()
    if code == 2:
        assert len([line for line in lines if line.startswith("error:")]) == 1 and lines[-1].startswith("error:"), \
            (args, err)
    else:
        assert code == 0, (args, code, out, err)
    assert "Traceback" not in out + err, (args, err)


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    """A project folder with a tiny run config and a one-version dataset file."""
    import yaml

    from test_hostile_inputs import run_config

    folder = tmp_path_factory.mktemp("fuzz-cli")
    (folder / "run.yaml").write_text(yaml.safe_dump(run_config(folder)))
    shutil.copy(DATA / "dataset_v1.h5", folder / "data.h5")
    return folder


def _fuzz(name: str, examples: int, project: Path):
    @budget(examples)
    @given(COMMANDS[name])
    def run(args):
        holds(args, project)
        shutil.rmtree(project / "whiskit-out", ignore_errors=True)
    run()


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_fuzz_command_exits_0_or_2_with_one_error_line(name, project):
    _fuzz(name, FAST, project)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_fuzz_command_long_run(name, project):
    _fuzz(name, SLOW, project)


FOUND = [   # argument lists the fuzzer found giving a traceback, kept for every run
    ["export", "whiskit", "data.h5", "--out", "whiskit-out", "--trial", "9" * 40],   # OverflowError in numpy
]


@pytest.mark.parametrize("args", FOUND, ids=range(len(FOUND)))
def test_command_lines_the_fuzzer_found(args, project):
    holds(args, project)


# --------------------------------------------------------------------------- meshes (`trial --scene mesh:PATH`)

CUBE = [(0, 0, 0), (0.01, 0, 0), (0, 0.01, 0), (0, 0, 0.01)]
TETRA = [(1, 2, 3), (1, 2, 4), (1, 3, 4), (2, 3, 4)]      # OBJ indices are 1-based


def obj_text(vertices, faces) -> bytes:
    return "".join([*(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices),
                    *(f"f {a} {b} {c}\n" for a, b, c in faces)]).encode()


coordinates = st.one_of(st.floats(-0.05, 0.05), st.sampled_from([float("nan"), float("inf"), 1e300, -1e300, 0.0]))
geometry = st.tuples(st.lists(st.tuples(coordinates, coordinates, coordinates), max_size=6),
                     st.lists(st.tuples(*[st.integers(-3, 8)] * 3), max_size=6))


def mesh_files():
    from test_fuzz_parsers import damaged

    valid = obj_text(CUBE, TETRA)
    return st.one_of(st.tuples(st.just(".obj"), damaged(valid)),
                     st.tuples(st.just(".obj"), geometry.map(lambda g: obj_text(*g))),
                     st.tuples(st.sampled_from([".ply", ".stl"]), st.binary(max_size=200)))


def _fuzz_mesh(examples: int, project: Path):
    @budget(examples)
    @given(mesh_files())
    def run(mesh):
        suffix, data = mesh
        path = project / f"scene{suffix}"
        path.write_bytes(data)
        holds(["trial", *CHEAP_TRIAL, "--scene", f"mesh:{path}"], project)
    run()


def test_fuzz_mesh_scene_exits_0_or_2_with_one_error_line(project):
    _fuzz_mesh(FAST, project)


@pytest.mark.slow
def test_fuzz_mesh_scene_long_run(project):
    _fuzz_mesh(SLOW, project)


@pytest.mark.parametrize("vertices", [[(0, 0, 0)] * 3, [(0, 0, 0), (0.01, 0, 0), (0.02, 0, 0)]], ids=["point", "line"])
def test_a_mesh_of_zero_area_triangles_is_one_error_line(vertices, project):
    """Such a mesh ran to `ok` as an obstacle nothing can touch."""
    path = project / "flat.obj"
    path.write_bytes(obj_text(vertices, [(1, 2, 3)]))
    code, _, err = run_main(["trial", *CHEAP_TRIAL, "--scene", f"mesh:{path}"], project)
    assert code == 2 and "zero area" in err and str(path) in err, err


def scan_files():
    from test_fuzz_parsers import POINTS, damaged

    return st.tuples(st.sampled_from([".ply", ".xyz", ".pts", ".pcd"]), damaged(POINTS) | st.binary(max_size=120))


def _fuzz_scans(examples: int, project: Path):
    @budget(examples)
    @given(scan_files())
    def run(scan):
        suffix, data = scan
        shutil.rmtree(project / "scans", ignore_errors=True)
        (project / "scans").mkdir()
        (project / "scans" / f"scan{suffix}").write_bytes(data)
        holds(["build-meshes", "--scans", "scans", "--out", "meshes-out", "--force"], project)
    run()


def test_fuzz_build_meshes_exits_0_or_2_with_one_error_line(project):
    _fuzz_scans(FAST, project)


@pytest.mark.slow
def test_fuzz_build_meshes_long_run(project):
    _fuzz_scans(SLOW, project)


def test_a_mesh_over_the_triangle_limit_is_one_error_line(project, monkeypatch):
    """A 2-million-triangle scene ran > 400 s with no word; the limit (174 762, pybullet's most)
    is lowered here through its environment variable."""
    path = project / "tetra.obj"
    path.write_bytes(obj_text(CUBE, TETRA))
    monkeypatch.setenv("PIPELINE_MAX_MESH_FACES", "3")
    code, _, err = run_main(["trial", *CHEAP_TRIAL, "--scene", f"mesh:{path}"], project)
    assert code == 2 and "triangles: 4, more than 3 (PIPELINE_MAX_MESH_FACES)" in err, err
    monkeypatch.setenv("PIPELINE_MAX_MESH_FACES", "many")
    assert run_main(["trial", *CHEAP_TRIAL, "--scene", f"mesh:{path}"], project)[0] == 2


def test_a_mesh_beyond_pybullets_vertex_limit_is_one_error_line(project):
    """131 073 vertices (pybullet takes 131 072): `pybullet.error` traceback before."""
    path = project / "many-vertices.obj"
    zigzag = [(0.03 + 1e-7 * i, 1e-3 * (i % 2), 1e-3 * (i % 3)) for i in range(131_073)]
    path.write_bytes(obj_text(zigzag, [(i, i + 1, i + 2) for i in range(1, 131_072, 3)]))
    code, _, err = run_main(["trial", *CHEAP_TRIAL, "--engine", "bullet", "--scene", f"mesh:{path}"], project)
    assert code == 2 and "pybullet cannot take this mesh (131073 vertices" in err, err
