"""Every model extension on both engines: a small 3-D release of a curved whisker, simulated by
Bullet, by MuJoCo and by the linearised chain of the diagnosis (exact in time, no shared
stepping code), must agree — and must differ from the same release without the extension,
so that an engine that ignored it would fail. A toy load defined here (one class, one
registration line) shows that a new load-type effect needs nothing else."""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.engine import EngineSimulator
from pipeline.diagnosis.fastsim import FastSimulator, PreparedTrial
from pipeline.engines.linear.chain import linearise
from pipeline.measurements import ReleaseDrive, Trial
from pipeline.model.effects.base import Parameter
from pipeline.model.effects.loads import LinearForm, LoadEffect
from pipeline.model.effects.registry import EFFECTS, make_effect
from pipeline.model.rotations import skew
from pipeline.model.physics import build_physics
from pipeline.model.whisker import WhiskerGeometry

CURVED = WhiskerGeometry(30e-3, 60e-6, 15e-6, 12.0)
MATERIAL = MaterialConfig()
PROBE = 0.6
PUSH_M = np.array([0.0, 0.3e-3, 0.2e-3])      # probe displacement: 1 % of the length, 3-D
DURATION_S = 0.04

# (extension, parameters): strong enough to change the release by many times the tolerance
CASES = {
    "follicle": ("follicle", {"k_f": 5e-6, "c_f": 2e-9}),
    "stiffness_gradient": ("stiffness_gradient", {"gamma": -1.0}),
    "damping_gradient": ("damping_gradient", {"gamma": 5.0}),
    "density": ("density", {"gradient": 1.5, "scale": 1.0}),
    "length": ("length", {"scale": 0.8}),
    "drag_linear": ("drag", {"linear": 2e-3, "quadratic": 0.0}),
    "drag_quadratic": ("drag", {"linear": 1e-7, "quadratic": 40.0}),
    "gravity": ("gravity", {"g": 40.0}),
    "twist": ("twist", {"g_over_e": 0.03}),
}


def _prepared(physics) -> list[PreparedTrial]:
    rest = linearise(physics).rest_points(np.array([PROBE]))[0]
    time_s = np.arange(int(DURATION_S * 1000) + 1) / 1000.0
    fractions = np.array([0.3, 0.6, 1.0])
    trial = Trial("release", time_s, fractions, np.zeros((len(time_s), 3, 3)),
                  ReleaseDrive(PROBE, rest + PUSH_M), 1000.0)
    return [PreparedTrial(trial, (0.0, 0.0, -1.0))]


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1))))


@pytest.fixture(scope="module")
def baseline():
    physics = build_physics(CURVED, MATERIAL)
    return FastSimulator().simulate(physics, _prepared(physics))[0]


@pytest.mark.parametrize("case", CASES)
def test_extension_runs_on_both_engines_as_the_linear_model_predicts(case, baseline):
    name, values = CASES[case]
    physics = build_physics(CURVED, MATERIAL, (make_effect(name, **values),))
    prepared = _prepared(physics)
    linear = FastSimulator().simulate(physics, prepared)[0]
    bullet, mujoco = (EngineSimulator(engine).simulate(physics, prepared)[0] for engine in ("bullet", "mujoco"))
    swing = float(np.abs(linear - linear[-1]).max())
    effect = _rms(linear, baseline)
    tolerance = 0.015 * swing         # measured 0.4–0.9 % (step size, terms the linear model drops)
    assert effect > 3 * tolerance, f"{case}: effect {effect:.3g} m too small to test"
    assert _rms(bullet, linear) < tolerance
    assert _rms(mujoco, linear) < tolerance
    # the engines' steps differ by h²·K in the metric (MuJoCo folds h·K·v into its damping,
    # pipeline.engines.stepping); measured 3e-4–1e-3 (≈ 1e-6 with the same step)
    assert _rms(bullet, mujoco) < 3e-3 * swing


@pytest.mark.parametrize("engine", ("bullet", "mujoco"))
@pytest.mark.parametrize("linear, quadratic", [(1e-3, 0.0), (1e-7, 40.0)], ids=["linear", "quadratic"])
def test_drag_moment_of_a_steadily_turning_whisker_is_the_integral_of_the_drag_law(engine, linear, quadratic):
    """A stiff straight whisker turned at constant ω about its base: once its start transient has
    died, the base moment balances the drag alone, M = ∫ f(ω·s)·s ds with f the drag per length
    (c·v + ½ρC_d·d(s)·v², ρ = 1.2 kg/m³) — integrated here on a fine grid, not by the engines'
    per-link quadrature and not through the joint layout."""
    from pipeline.config.physics import EngineConfig, ModelConfig
    from pipeline.engines import create_engine
    from pipeline.model.array import single_whisker
    from pipeline.model.kinematics import Pose, ProtractionDrive
    from pipeline.scenes import empty

    straight = WhiskerGeometry(30e-3, 60e-6, 15e-6, 0.0)
    material = MaterialConfig(youngs_modulus_gpa=20.0)
    omega = 20.0                                                            # rad/s
    array = single_whisker(straight, material, extensions=(make_effect("drag", linear=linear, quadratic=quadratic),))
    drive = ProtractionDrive(np.array([0.0, 1.0]), np.array([0.0, omega]), interpolation="linear")
    with create_engine(ModelConfig(material=material, engine=EngineConfig(name=engine)), array) as simulator:
        out = simulator.run(empty(), Pose(), drive, 0.06)
    s = np.linspace(0.0, straight.arc_length_m, 20001)
    diameter = 2 * (straight.base_radius_m + (straight.tip_radius_m - straight.base_radius_m) * s / s[-1])
    speed = omega * s
    expected = np.trapezoid((linear * speed + 0.5 * 1.2 * quadratic * diameter * speed ** 2) * s, s)
    moment = np.linalg.norm(out.base_wrench[-10:, 0, 3:].astype(float), axis=1)
    np.testing.assert_allclose(moment, expected, rtol=0.005)      # measured −0.05 % / −0.02 %


@dataclass(frozen=True)
class LinkFriction(LoadEffect):
    """Toy load: f_l = −b·v_l on each link's centre of mass (world velocity), no torque. Linear
    form at the rest centres c_l with Jacobians J_l: C = b·Σ J_lᵀJ_l, D = −b·Σ J_lᵀ·[c_l]×,
    base wrench F = Σ f_l, M = Σ c_l × f_l with v_l = J_l·q̇ + ω × c_l."""

    name: ClassVar[str] = "link_friction"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("b", "N*s/m", 1e-6, 0.0, 1e-3, False, "friction per link"),
    )
    b: float = 1e-6
    needs_velocity: ClassVar[bool] = True
    depends_on_pose: ClassVar[bool] = False

    def link_forces(self, chain, state):
        force = -self.b * state.velocity_m_s
        return force, np.zeros_like(force)

    def linear_form(self, rest):
        com = rest.com_m
        jac = rest.jacobian(com, np.arange(len(com)))                        # [N, 3, n]

        def wrench(rate, omega):
            force = -self.b * (np.einsum("lai,ti->tla", jac, rate) + np.cross(omega[:, None, :], com))
            return force.sum(axis=1), np.cross(com, force).sum(axis=1)

        return LinearForm(damping=self.b * np.einsum("lai,laj->ij", jac, jac),
                          rate_coupling=-self.b * np.einsum("lai,lab->ib", jac, skew(com)), wrench=wrench)


def test_a_toy_load_effect_runs_through_the_linear_chain_and_an_engine(monkeypatch, baseline):
    monkeypatch.setitem(EFFECTS, LinkFriction.name, LinkFriction)           # its registration
    physics = build_physics(CURVED, MATERIAL, (make_effect("link_friction", b=3e-6),))
    prepared = _prepared(physics)
    linear = FastSimulator().simulate(physics, prepared)[0]
    mujoco = EngineSimulator("mujoco").simulate(physics, prepared)[0]
    swing = float(np.abs(linear - linear[-1]).max())
    effect = _rms(linear, baseline)
    assert effect > 0.05 * swing, f"effect {effect:.3g} m too small to test"
    assert _rms(mujoco, linear) < 0.015 * swing
