"""The measurements of benchmarks/bench_stick_slip.py (issue 24): how deep the centre line lies
inside a peg, the peg's normal at a contact, and the peaks at the dataset's sampling."""

import importlib.util
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from pipeline.config.physics import ModelConfig

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_stick_slip.py"
_SPEC = importlib.util.spec_from_file_location("bench_stick_slip", _PATH)
bench = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(bench)


def test_the_centre_line_depth_inside_a_cylinder_and_a_faceted_peg():
    """A chain through the peg's axis is a radius deep in the cylinder and an apothem
    (R·cos(π/n)) deep in the n-sided prism; a chain 0.1 mm clear of the cylinder is −0.1 mm."""
    radius, centre = 0.5e-3, np.array([1e-3, 2e-3])
    through = np.array([[[0.0, 2e-3, 0.0], [2e-3, 2e-3, 0.0]]])              # [T=1, 2 nodes, 3]
    clear = through + [0.0, radius + 0.1e-3, 0.0]
    assert np.isclose(bench.axis_depth_m(through, centre, radius, 0)[0], radius)
    assert np.isclose(bench.axis_depth_m(through, centre, radius, 8)[0], radius * np.cos(np.pi / 8))
    assert np.isclose(bench.axis_depth_m(clear, centre, radius, 0)[0], -0.1e-3)
    # beside the prism's top vertex: the distance to the nearest side's plane
    assert np.isclose(bench.axis_depth_m(clear, centre, radius, 8)[0], -0.1e-3 * np.cos(np.pi / 8))


def test_the_normal_is_radial_on_the_cylinder_and_the_side_s_on_a_facet():
    point = np.array([[np.cos(np.radians(10.0)), np.sin(np.radians(10.0))]])
    assert np.allclose(bench.surface_normal(point, np.zeros(2), 0), point)
    side = np.radians(22.5)
    assert np.allclose(bench.surface_normal(point, np.zeros(2), 8), [[np.cos(side), np.sin(side)]])


def test_a_coarse_sample_counts_the_contacts_of_the_samples_it_skips():
    """Every 2nd of 6 samples taken; only fine sample 3 touches: the sample taken at 4 (which
    covers 3 and 4) is in contact and carries the peak, the one at 2 is not."""
    wrench = np.zeros((6, 1, 6))
    wrench[:, 0, 5] = [1.0, 2.0, 9.0, 3.0, 4.0, 5.0]                          # |M| = Mz
    wrench[:, 0, 1] = [0.1, 0.2, 0.9, 0.3, 0.4, 0.5]
    contact = np.zeros((6, 1, 1), bool)
    contact[3] = True
    output = SimpleNamespace(time_s=np.arange(6) * 1e-4, base_wrench=wrench, contact=contact)
    assert bench.peaks(output, 2) == (4.0, 0.4)
    assert bench.peaks(output, 1) == (3.0, 0.3)


def test_mujoco_s_tip_sliding_over_a_faceted_peg_converges_in_the_step():
    """RC1's tip (85 % of S) swept at 500 °/s over an 8-sided peg, μ = 0.5: MuJoCo's peaks at the
    default step are within 5 % of those at half of it, and the whisker's centre line stays
    outside the peg. With the tip read at its own 16 µm radius its axis went through the peg's
    edges (11 % of the contact samples, 0.42 mm deep) and the peaks were 24 % (|M|) and 40 %
    (F_t) above half the step's."""
    args = SimpleNamespace(fraction=0.85, mu=0.5, speed=500.0, sweep=40.0, rate=10000.0)
    default, half = (bench.run(ModelConfig(), "mujoco", "RC1", 8, divisor, args) for divisor in (1, 2))
    for key in ("peak_moment_nm", "peak_transverse_n"):
        assert abs(default[key] / half[key] - 1) < 0.05, (key, default[key], half[key])
    assert default["axis_through_share"] < 0.02 and default["axis_deepest_um"] < 16.0
