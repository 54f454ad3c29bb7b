"""The effects of pipeline/model/effects/ compose by their ``order``, not by the order a config
lists them: the same whisker, bit for bit, whatever that order; a material's implied effect
gives way to one given explicitly; a load whose parameters are all zero is no load."""

import numpy as np

from pipeline.config.material import MaterialConfig
from pipeline.engines.linear.chain import linearise
from pipeline.model.effects.registry import EFFECTS, make_effect, material_effects
from pipeline.model.physics import build_physics
from pipeline.model.whisker import WhiskerGeometry

CURVED = WhiskerGeometry(30e-3, 60e-6, 15e-6, 12.0)
MATERIAL = MaterialConfig(links=8)


def _physics(*effects, material=MATERIAL):
    return build_physics(CURVED, material, tuple(make_effect(name, **values) for name, values in effects))


def test_the_listing_order_of_effects_does_not_change_the_whisker():
    listed = [("mass_damping", {"alpha": 30.0}), ("drag", {"linear": 2e-4, "quadratic": 1.0}),
              ("base_segment", {}), ("follicle", {"k_f": 5e-6, "c_f": 2e-9}), ("gravity", {"g": 9.81})]
    forward, backward = _physics(*listed), _physics(*listed[::-1])
    assert [load.name for load in forward.loads] == ["gravity", "drag", "mass_damping"]
    assert forward.loads == backward.loads and forward.follicle == backward.follicle
    a, b = linearise(forward), linearise(backward)
    for name in ("mass", "stiffness", "damping", "rate_coupling", "gravity"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_an_effect_given_replaces_the_one_the_material_implies():
    material = MaterialConfig(links=8, gravity=True, follicle={"kind": "compliant"}, base_segment=False)
    assert [e.name for e in material_effects(material)] == ["follicle", "gravity"]
    physics = _physics(("gravity", {"g": 3.0}), ("follicle", {"k_f": 2e-6, "c_f": 1e-9}), material=material)
    assert [load.gravity_m_s2 for load in physics.loads] == [3.0]
    assert physics.follicle == EFFECTS["follicle"](2e-6, 1e-9)


def test_a_load_with_every_parameter_zero_is_no_load():
    off = (EFFECTS["gravity"](0.0), EFFECTS["drag"](0.0, 0.0), EFFECTS["mass_damping"](0.0))
    assert build_physics(CURVED, MATERIAL, off).loads == ()         # (a zero load off: the free path stays on)
    assert [load.name for load in build_physics(CURVED, MATERIAL, (EFFECTS["drag"](0.0, 2.0),)).loads] == ["drag"]
