"""The CLI shell and the config loader: fast help, one-line errors, precedence."""

import subprocess
import sys
import time
from pathlib import Path

import pytest

from pipeline.config import load_config
from pipeline.config.physics import ModelConfig
from pipeline.config.simulate import SimulateConfig
from pipeline.errors import UserError

REPO = Path(__file__).resolve().parents[2]


def _pipeline(*args, cwd=REPO):
    return subprocess.run([sys.executable, "-m", "pipeline.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=120)


def test_help_lists_commands_and_is_fast():
    start = time.perf_counter()
    result = _pipeline("--help")
    elapsed = time.perf_counter() - start
    assert result.returncode == 0
    for command in ("info", "run"):
        assert command in result.stdout
    # interpreter start included; the heavy libraries must not be imported for --help
    assert elapsed < 3.0


def test_help_imports_no_heavy_library():
    code = ("import sys; from pipeline import cli; "
            "heavy = [m for m in ('open3d', 'pybullet', 'rerun', 'dask', 'distributed', 'h5py') "
            "if m in sys.modules]; print(','.join(heavy))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO)
    assert result.stdout.strip() == ""


def test_info_prints_versions_and_config():
    result = _pipeline("info", "--json")
    assert result.returncode == 0, result.stderr
    assert '"pybullet"' in result.stdout and '"model.yaml"' in result.stdout


def test_bad_config_value_gives_one_line_error(tmp_path):
    (tmp_path / "configs").mkdir()
    (tmp_path / "configs" / "model.yaml").write_text("material:\n  links: 500\n")
    result = _pipeline("info", "--configs", str(tmp_path / "configs"))
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("error: ")
    assert "model.yaml" in lines[0] and "material.links" in lines[0] and "120" in lines[0]
    assert "Traceback" not in result.stderr


def test_debug_flag_shows_traceback(tmp_path):
    (tmp_path / "model.yaml").write_text("material:\n  links: 500\n")
    result = _pipeline("--debug", "info", "--configs", str(tmp_path))
    assert result.returncode == 2 and "Traceback" in result.stderr


def test_precedence_flag_over_env_over_file(tmp_path):
    path = tmp_path / "model.yaml"
    path.write_text("material:\n  links: 30\n  damping_ratio: 0.2\n")
    env = {"PIPELINE_MODEL_MATERIAL__LINKS": "40", "PIPELINE_MODEL_ENGINE__DT_S": "5e-5"}
    config, source = load_config(ModelConfig, path, env_prefix="PIPELINE_MODEL_", environ=env,
                                 overrides={"material": {"links": 50}})
    assert config.material.links == 50                 # flag
    assert config.engine.dt_s == 5e-5                   # environment
    assert config.material.damping_ratio == 0.2         # file
    assert config.material.youngs_modulus_gpa == ModelConfig().material.youngs_modulus_gpa
    assert source.origin_of(("material", "links")) == "command-line flag"


@pytest.mark.parametrize("text, needle", [
    ("material:\n  youngs_modulus_gpa: -3\n", "material.youngs_modulus_gpa"),
    ("materal: {}\n", "unknown field 'materal'"),
    ("engine:\n  dt_s: 0.5\n", "engine.dt_s"),
    ("[unclosed\n", "not valid YAML"),
])
def test_config_errors_name_the_field(tmp_path, text, needle):
    path = tmp_path / "model.yaml"
    path.write_text(text)
    with pytest.raises(UserError) as info:
        load_config(ModelConfig, path)
    assert needle in str(info.value)
    assert "\n" not in str(info.value)


def test_env_error_names_the_variable():
    with pytest.raises(UserError, match="environment"):
        load_config(ModelConfig, env_prefix="PIPELINE_MODEL_",
                    environ={"PIPELINE_MODEL_MATERIAL__LINKS": "1"})


@pytest.mark.parametrize("text", ["poses:\n  rim_margin_mm: -1\n", "poses:\n  max_attempts: 0\n"])
def test_pose_sampling_errors_name_the_field(tmp_path, text):
    path = tmp_path / "simulate.yaml"
    path.write_text(text)
    with pytest.raises(UserError) as info:
        load_config(SimulateConfig, path)
    assert f"poses.{text.split()[1].rstrip(':')}" in str(info.value)
    assert "\n" not in str(info.value)
