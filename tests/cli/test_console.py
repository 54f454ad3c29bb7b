"""What a person reads: rounded numbers with SI units, "next:" hints, and options that mean
the same on every command (`--json` everywhere, `--engine` a choice)."""

import json

import pytest
import typer

from pipeline import console
from pipeline.cli import app


@pytest.mark.parametrize("key, value, text", [
    ("max_moment_N_m", 8.13429505797103e-06, "8.13 µN·m"),     # not "nm": newton metres, SI prefix
    ("cpu_seconds", 1.360057892, "1.36 s"),
    ("write_seconds", 0.029, "29.0 ms"),
    ("cpu_seconds_per_trial", 0.8283, "828 ms"),
    ("sampling_rate_hz", 1000.0, "1.00 kHz"),
    ("size_mb", 0.16, "0.160 MB"),                              # MB stays MB: no prefix on a prefix
    ("duration_s", 0.25, "250 ms"),
    ("physics_share_of_cpu", 0.87412, "0.874"),
    ("whiskers", 30, "30"),
    ("complete", True, "yes"),
    ("pose_acceptance_rate", None, "—"),
    ("scenes_ok", {"pegs-active": 2, "wall": 1}, "pegs-active 2, wall 1"),
])
def test_values_are_rounded_with_their_units(key, value, text):
    assert console.value_text(key, value) == text


def test_labels_drop_the_unit_suffix():
    assert console.label("max_moment_N_m") == "max moment"
    assert console.label("cpu_seconds_per_trial") == "cpu time per trial"
    assert console.label("sampling_rate_hz") == "sampling rate"


def test_fitted_parameters_share_one_prefix(capsys):
    from rich.console import Console

    table = console.parameters_table({"E": {"value": 7.4136e9, "sd": 9e7, "unit": "Pa"},
                                      "follicle.k_f": {"value": 5e-7, "sd": None, "unit": "N*m/rad"},
                                      "zeta": {"value": 0.024242, "sd": 0.013, "unit": "1"}}, "fit")
    Console(width=100).print(table)
    rows = {line.split("│")[1].strip(): [c.strip() for c in line.split("│")[2:5]]
            for line in capsys.readouterr().out.splitlines() if line.startswith("│")}
    assert rows == {"E": ["7.41", "0.090", "GPa"], "follicle.k_f": ["500", "—", "nN·m/rad"],
                    "zeta": ["0.0242", "0.013", ""]}


def test_json_has_no_nan(capsys):
    console.print_json({"f1_hz": float("nan"), "modes": [1.0, float("inf")]})
    assert json.loads(capsys.readouterr().out) == {"f1_hz": None, "modes": [1.0, None]}


def _leaf_commands():
    def walk(command, path):
        if hasattr(command, "commands"):                 # a group (typer may bundle its own click)
            for name, sub in command.commands.items():
                yield from walk(sub, path + [name])
        else:
            yield " ".join(path), command
    yield from walk(typer.main.get_command(app), [])


def test_every_command_has_json_and_engine_is_a_choice():
    from typer.testing import CliRunner

    commands = dict(_leaf_commands())
    assert {"trial", "simulate", "run", "view", "datasets join", "datasets list", "info"} <= set(commands)
    for name, command in commands.items():
        options = {opt for param in command.params for opt in getattr(param, "opts", [])}
        assert "--json" in options, name
        if "--engine" in options:
            shown = CliRunner().invoke(app, [*name.split(), "--help"], env={"COLUMNS": "200"}).output
            assert "<bullet|mujoco>" in shown, name


def test_trial_summary_reads_like_a_lab_tool(pipeline_cli):
    result = pipeline_cli("trial", "--engine", "mujoco", "--whiskers", "RC1", "--duration-s", "0.02",
                          "--scene", "pegs-active")
    assert result.returncode == 0, result.stderr
    assert "N·m" in result.stdout and "max moment" in result.stdout and "_nm" not in result.stdout
    assert "next: " in result.stdout
    data = json.loads(pipeline_cli("trial", "--engine", "mujoco", "--whiskers", "RC1", "--duration-s", "0.02",
                                   "--scene", "pegs-active", "--json").stdout)
    assert data["engine"] == "mujoco" and data["max_moment_N_m"] > 0


def test_unknown_engine_is_one_error_line(pipeline_cli):
    result = pipeline_cli("trial", "--engine", "physx")
    assert result.returncode == 2 and result.stderr.startswith("error:") and "physx" in result.stderr
    assert "Traceback" not in result.stderr
