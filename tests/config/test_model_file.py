"""The fitted-model file (docs/model_file.md): save/load round trip, strict validation, configs
that name it, and the loop synth → diagnose/calibrate --save-model → trial/resonance/simulate
--model on both engines."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from pipeline.config.loader import load_config
from pipeline.config.model_file import read_model_file
from pipeline.config.physics import MaterialConfig, ModelConfig
from pipeline.diagnosis.diagnose import CONTINUUM
from pipeline.config.simulate import SimulateConfig
from pipeline.errors import UserError
from pipeline.model.effects.follicle import CompliantFollicle
from pipeline.model.effects.registry import model_parts
from pipeline.model.effects.stiffness_gradient import StiffnessGradient
from pipeline.model.whisker import WhiskerGeometry

REPO = Path(__file__).resolve().parents[2]
WHISKER = {"name": "C2", "arc_length_mm": 30, "base_diameter_um": 120, "tip_diameter_um": 30,
           "curvature_per_mm": 0.01}
GEOMETRY = WhiskerGeometry(30e-3, 60e-6, 15e-6, 10.0)
RESONANCE_FLAGS = ("--length-mm", 30, "--base-diameter-um", 120, "--tip-diameter-um", 30, "--curvature-per-mm", 0.01)
HIDDEN = {"follicle": {"k_f": 6.0e-6, "c_f": 2.0e-9}, "stiffness_gradient": {"gamma": -1.0}}


def cli(*args, cwd=REPO, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipeline.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)


def ok(*args, **kwargs) -> str:
    done = cli(*args, **kwargs)
    assert done.returncode == 0, done.stderr
    return done.stdout


def synth_config(tmp_path: Path, extensions=HIDDEN) -> Path:
    """A small synth config: the C2 whisker with ``extensions`` hidden, four short trials."""
    path = tmp_path / "synth.yaml"
    path.write_text(yaml.safe_dump({
        "seed": 3, "whisker": WHISKER, "material": {"youngs_modulus_gpa": 5.5, "damping_ratio": 0.15},
        "extensions": extensions, "duration_s": 0.2, "tracking": {"noise_mm": 0.05},
        "trials": [{"name": "release_y", "release": {"contact_fraction": 0.7, "deflection_mm": [0, 1.5, 0]}},
                   {"name": "release_z", "release": {"contact_fraction": 0.6, "deflection_mm": [0, 0, 1.5]}},
                   {"name": "pulse_yaw", "pulse": {"weights": [1, 0, 0], "amplitude_deg": 30}},
                   {"name": "pulse_pitch", "pulse": {"weights": [0, 1, 0], "amplitude_deg": 20}}]}))
    return path


def save_hand_model(path: Path, data_file: Path, extensions=HIDDEN, e_gpa: float = 5.5) -> Path:
    """A model file written through the library (as --save-model does), with the given values."""
    from pipeline.diagnosis.calibrate import modal_summary
    from pipeline.diagnosis.parameters import ModelSpec
    from pipeline.diagnosis.saved_model import save_model
    from pipeline.model.effects.registry import effects_from

    spec = ModelSpec(MaterialConfig(youngs_modulus_gpa=e_gpa, damping_ratio=0.15),
                     effects_from(extensions, "test"))
    params = {"E": {"value": e_gpa * 1e9, "sd": 2e7, "unit": "Pa"},
              "follicle.k_f": {"value": 6e-6, "sd": 1e-7, "unit": "N*m/rad"}}
    fit = {"method": "calibrate", "metric": "msa_eq4a+4b", "error": 0.01, "whisker": "C2",
           **modal_summary(spec, GEOMETRY)}
    return save_model(path, spec, params, [data_file], fit)


def linear_f1(config: ModelConfig) -> float:
    """The diagnosis' linear model's first in-plane (damped) frequency of the C2 whisker."""
    from pipeline.engines.linear.modal import damped_modes
    from pipeline.engines.linear.chain import linearise
    from pipeline.model.physics import build_physics

    material, extensions = model_parts(config)
    freqs, _, in_plane = damped_modes(linearise(build_physics(GEOMETRY, material, extensions)))
    return float(freqs[in_plane][0])


@pytest.fixture
def data_file(tmp_path) -> Path:
    path = tmp_path / "data.h5"
    path.write_bytes(b"stand-in for a measurement file: only its hash is recorded")
    return path


# -- the file ------------------------------------------------------------------------------------
def test_round_trip_keeps_material_extensions_uncertainties_and_provenance(tmp_path, data_file):
    path = save_hand_model(tmp_path / "m.yaml", data_file)
    loaded = read_model_file(path)
    content = loaded.content
    assert content.material.youngs_modulus_gpa == 5.5 and content.material_sd.youngs_modulus_gpa == pytest.approx(0.02)
    assert content.material_sd.damping_ratio is None                       # not fitted: no sd
    assert content.extensions["follicle"]["k_f"].value == 6e-6 and content.extensions["follicle"]["k_f"].sd == 1e-7
    assert content.extensions["follicle"]["c_f"].sd is None and content.extensions["follicle"]["c_f"].unit == "N*m*s/rad"
    assert content.extensions["stiffness_gradient"]["gamma"].value == -1.0
    assert content.provenance.data[0].sha256 == hashlib.sha256(data_file.read_bytes()).hexdigest()
    assert "numpy" in content.provenance.packages and content.provenance.command
    assert loaded.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()

    material, extensions = model_parts(ModelConfig(file=path))
    assert material == content.material
    assert extensions == (CompliantFollicle(6e-6, 2e-9), StiffnessGradient(-1.0))
    # what the saving spec predicted is what the loaded model predicts
    assert linear_f1(ModelConfig(file=path)) == pytest.approx(content.provenance.fit.f1_hz, rel=1e-12)


def test_configs_name_the_file_relative_to_themselves_and_override_it(tmp_path, data_file):
    folder = tmp_path / "configs"
    folder.mkdir()
    save_hand_model(folder / "m.yaml", data_file)
    config_path = folder / "model.yaml"
    config_path.write_text(yaml.safe_dump({"file": "m.yaml", "material": {"damping_ratio": 0.2},
                                           "extensions": {"follicle": {"c_f": 1e-9}}}))
    config, _ = load_config(ModelConfig, config_path)
    assert config.file == (folder / "m.yaml").resolve()
    assert config.material.youngs_modulus_gpa == 5.5 and config.material.damping_ratio == 0.2
    assert config.extensions == {"follicle": {"k_f": 6e-6, "c_f": 1e-9}, "stiffness_gradient": {"gamma": -1.0}}
    again = ModelConfig.model_validate(config.model_dump(mode="json"))   # a dataset's stored copy
    assert again == config and again.model_file.sha256 == config.model_file.sha256

    run = folder / "simulate.yaml"
    run.write_text(yaml.safe_dump({"model": {"file": "m.yaml", "whiskers": "RC1"}}))
    nested, _ = load_config(SimulateConfig, run)
    assert model_parts(nested.model)[1] == (CompliantFollicle(6e-6, 2e-9), StiffnessGradient(-1.0))


def test_synth_uses_the_model_as_the_truths_base(tmp_path, data_file):
    from pipeline.diagnosis.synth import load_synth_config, true_spec

    save_hand_model(tmp_path / "m.yaml", data_file, e_gpa=4.2)
    path = synth_config(tmp_path, extensions={"gravity": {"g": 9.81}})
    spec = true_spec(load_synth_config(path, {"model_file": str(tmp_path / "m.yaml")}))
    assert spec.material.youngs_modulus_gpa == pytest.approx(5.5)            # the synth config's own value wins
    assert spec.material.damping_ratio == pytest.approx(0.15)
    assert [e.name for e in spec.extensions] == ["follicle", "stiffness_gradient", "gravity"]


def _bad_file(tmp_path: Path, data_file: Path, change) -> Path:
    path = save_hand_model(tmp_path / "good.yaml", data_file)
    data = yaml.safe_load(path.read_text())
    change(data)
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    return bad


@pytest.mark.parametrize("change, message", [
    (lambda d: d["material"].update(colour="red"), "unknown field 'material.colour'"),
    (lambda d: d["material"].update(links="many"), "field 'material.links' = 'many'"),
    (lambda d: d.pop("provenance"), "field 'provenance'"),
    (lambda d: d["extensions"]["follicle"]["k_f"].update(value=5.0), "k_f = 5.0 N*m/rad is outside"),
    (lambda d: d["extensions"]["follicle"]["k_f"].update(unit="mN*m/rad"), "'extensions.follicle.k_f.unit'"),
    (lambda d: d["extensions"].update(wings={"span": {"value": 1.0, "unit": "m"}}), "unknown model extension 'wings'"),
    (lambda d: d["extensions"]["follicle"]["k_f"].update(sd=-1.0), "'extensions.follicle.k_f.sd'"),
])
def test_bad_files_are_one_line_errors_naming_file_and_field(tmp_path, data_file, change, message):
    bad = _bad_file(tmp_path, data_file, change)
    with pytest.raises(UserError) as error:
        model_parts(ModelConfig(file=bad))
    text = str(error.value)
    assert str(bad) in text and message in text and "\n" not in text


def test_cli_bad_model_file_exits_2_with_one_error_line(tmp_path, data_file):
    bad = _bad_file(tmp_path, data_file, lambda d: d["extensions"]["stiffness_gradient"]["gamma"].update(value=9.0))
    for args in (("trial", "--whiskers", "RC1", "--duration-s", "0.01"), ("resonance", *RESONANCE_FLAGS)):
        done = cli(*args, "--model", bad)
        assert done.returncode == 2 and done.stdout == ""
        assert done.stderr.count("\n") == 1 and done.stderr.startswith(f"error: model file {bad}")
        assert "gamma = 9.0" in done.stderr
    done = cli("trial", "--model", tmp_path / "missing.yaml")
    assert done.returncode == 2 and done.stderr == f"error: model file not found: {tmp_path / 'missing.yaml'}\n"


# -- the model in every engine ----------------------------------------------------------------
@pytest.mark.parametrize("engine", ["mujoco", "bullet"])
def test_resonance_of_the_model_matches_its_linear_model(tmp_path, data_file, engine):
    """Follicle + stiffness gradient on the engine: f1 within 1 % of the linear model's, which
    differs from the plain model's by far more (so the extensions must be in the engine)."""
    from pipeline.protocols.resonance import run_resonance

    path = save_hand_model(tmp_path / "m.yaml", data_file)
    config = ModelConfig(file=path, engine={"name": engine})
    predicted = read_model_file(path).content.provenance.fit.f1_hz
    plain = linear_f1(ModelConfig(material=config.material))
    assert abs(plain / predicted - 1) > 0.2
    assert run_resonance(GEOMETRY, config).f1_hz == pytest.approx(predicted, rel=0.01)


def test_trial_runs_the_model_on_both_engines_and_records_it(tmp_path, data_file):
    import pipeline.datasets as datasets

    path = save_hand_model(tmp_path / "m.yaml", data_file)
    moments = {}
    for engine in ("mujoco", "bullet"):
        out = tmp_path / f"{engine}.h5"
        summary = json.loads(ok("trial", "--model", path, "--engine", engine, "--whiskers", "RC1,RD2",
                                "--scene", "pegs-active", "--duration-s", "0.03", "--out", out, "--json"))
        moments[engine] = summary["max_moment_N_m"]
        with datasets.open_file(out) as ds:
            record = ds.provenance["model_file"]
            assert record["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
            assert record["content"] == path.read_text()
            assert ds.provenance["config"]["extensions"]["stiffness_gradient"] == {"gamma": -1.0}
    # against a peg (free whisking from the drive's steady start loads the base by inertia alone,
    # which the stiffness does not change)
    plain = json.loads(ok("trial", "--engine", "mujoco", "--whiskers", "RC1,RD2", "--scene", "pegs-active",
                          "--duration-s", "0.03", "--json"))
    assert moments["bullet"] == pytest.approx(moments["mujoco"], rel=0.05)
    assert abs(moments["mujoco"] / plain["max_moment_N_m"] - 1) > 0.05


def _simulate_records(tmp_path: Path, model: Path, trials: int) -> None:
    import pipeline.datasets as datasets

    config = tmp_path / "simulate.yaml"
    config.write_text(yaml.safe_dump({
        "trials": trials, "seed": 1, "model": {"whiskers": "RC1,RD1", "engine": {"name": "mujoco"}},
        "whisk": {"duration_s": 0.03}, "scenes": {"include": ["pegs-active", "wall"]},
        "dataset": {"root": str(tmp_path / "datasets"), "name": "fitted", "node_positions_every": 0},
        "cluster": {"workers": 1, "record_every": 0}}))
    summary = json.loads(ok("simulate", "--config", config, "--model", model, "--json"))
    assert summary["ok"] == trials
    with datasets.open_file(summary["dataset"]) as ds:
        record = ds.provenance["model_file"]
        assert record["path"] == str(model.resolve()) and record["content"] == model.read_text()
        assert record["sha256"] == hashlib.sha256(model.read_bytes()).hexdigest()
        assert ds.provenance["config"]["model"]["extensions"] == read_model_file(model).content.extension_values()


def test_simulate_dataset_records_the_model(tmp_path, data_file):
    _simulate_records(tmp_path, save_hand_model(tmp_path / "m.yaml", data_file), trials=4)


@pytest.fixture(scope="module")
def measurement(tmp_path_factory) -> Path:
    """The synthetic C2 measurement with a hidden follicle and stiffness gradient."""
    folder = tmp_path_factory.mktemp("measurement")
    ok("synth", "--config", synth_config(folder), "--out", folder / "m.h5")
    return folder / "m.h5"


def test_calibrate_saves_the_model_it_fitted(tmp_path, measurement):
    data = measurement
    out = json.loads(ok("calibrate", data, "--params", "E,zeta,stiffness_gradient.gamma",
                        "--save-model", tmp_path / "cal.yaml", "--json"))
    assert out["model_file"] == str(tmp_path / "cal.yaml")
    content = read_model_file(tmp_path / "cal.yaml").content
    assert content.provenance.fit.method == "calibrate" and content.provenance.data[0].path == str(data.resolve())
    gamma = content.extensions["stiffness_gradient"]["gamma"]
    assert gamma.value == pytest.approx(out["params"]["stiffness_gradient.gamma"]["value"])
    assert gamma.sd == pytest.approx(out["params"]["stiffness_gradient.gamma"]["sd"])
    assert content.material.youngs_modulus_gpa * 1e9 == pytest.approx(out["params"]["E"]["value"])
    assert linear_f1(ModelConfig(file=tmp_path / "cal.yaml")) == pytest.approx(out["modes"]["C2"]["f1_hz"], rel=1e-9)


def test_a_joint_fit_of_the_library_saves_its_model_under_the_law_it_was_fitted_with(tmp_path):
    """``calibrate --library --where trimmed=no --preset untrimmed_rayleigh --save-model``: the law
    the library's evidence picks, E and ζ1 as fitted, both D-row tables as the data, and the fit
    summary's f1 that of the saved model on the first fitted whisker."""
    from pipeline.diagnosis.calibrate import modal_summary
    from pipeline.diagnosis.parameters import ModelSpec
    from pipeline.measurements.library import load_library

    model = tmp_path / "library.yaml"
    out = json.loads(ok("calibrate", "--library", "--where", "trimmed=no", "--preset", "untrimmed_rayleigh",
                        "--save-model", model, "--json"))
    assert out["model_file"] == str(model) and out["damping_laws"]["picked"] == "rayleigh"
    content = read_model_file(model).content
    assert content.material.damping_model == "rayleigh"
    assert content.material.youngs_modulus_gpa * 1e9 == pytest.approx(out["params"]["E"]["value"])
    assert content.material.damping_ratio == pytest.approx(out["params"]["zeta"]["value"])
    assert content.material_sd.youngs_modulus_gpa * 1e9 == pytest.approx(out["params"]["E"]["sd"])
    assert [Path(d.path).stem for d in content.provenance.data] == list(out["sets"])
    d1 = next(r for t in load_library() if t.path.stem == "hartmann2003_Drow_vibration_table"
              for r in t.records if r.whisker == "D1")
    assert content.provenance.fit.whisker == "hartmann2003_Drow_vibration_table/D1"
    material, _ = model_parts(ModelConfig(file=model))
    assert modal_summary(ModelSpec(material), d1.geometry)["f1_hz"] == pytest.approx(content.provenance.fit.f1_hz,
                                                                                      rel=1e-9)


def test_diagnose_saves_its_final_model_or_the_baseline(tmp_path, measurement):
    for candidates, cause in (("follicle", "follicle"), ("gravity", "unexplained")):
        model = tmp_path / f"{candidates}.yaml"
        out = json.loads(ok("diagnose", measurement, "--candidates", candidates, "--save-model", model, "--json"))
        assert out["cause"] == cause and out["model_file"] == str(model)
        content = read_model_file(model).content
        assert content.provenance.fit.method == "diagnose" and content.provenance.fit.cause == cause
        assert content.material.youngs_modulus_gpa * 1e9 == pytest.approx(out["params"]["E"]["value"])
        assert content.material_sd.damping_ratio == pytest.approx(out["params"]["zeta"]["sd"])
        # every diagnose model has the continuum corrections (docs/measurements.md §9)
        assert set(content.extensions) == ({e.name for e in CONTINUUM}
                                           | ({"follicle"} if cause == "follicle" else set()))
        for name, entry in content.extensions.get("follicle", {}).items():
            assert entry.value == pytest.approx(out["params"][f"follicle.{name}"]["value"])
            assert entry.sd == pytest.approx(out["params"][f"follicle.{name}"]["sd"])
        assert linear_f1(ModelConfig(file=model)) == pytest.approx(content.provenance.fit.f1_hz, rel=1e-9)


@pytest.mark.slow
def test_synth_diagnose_save_model_then_every_engine_runs_it(tmp_path):
    """The issue's loop: hidden follicle + stiffness gradient → diagnose --save-model → trial and
    resonance on both engines (f1 within 1 % of the diagnosis' prediction) → a 20-trial dataset."""
    data, model = tmp_path / "m.h5", tmp_path / "m.yaml"
    ok("synth", "--config", synth_config(tmp_path), "--out", data)
    ok("diagnose", data, "--save-model", model)
    content = read_model_file(model).content
    assert content.provenance.fit.cause in content.extensions            # a named cause is in the file
    for engine in ("bullet", "mujoco"):
        ok("trial", "--model", model, "--engine", engine, "--whiskers", "RC1", "--duration-s", "0.03")
        f1 = json.loads(ok("resonance", *RESONANCE_FLAGS, "--model", model, "--engine", engine, "--json"))["f1_hz"]
        assert f1 == pytest.approx(content.provenance.fit.f1_hz, rel=0.01)
    _simulate_records(tmp_path, model, trials=20)
