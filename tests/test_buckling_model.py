"""The column-buckling model of benchmarks/stiffness_limit.py (docs/method-notes.md, "Limits"),
checked where it has a closed form, so its prediction for the 20-box column can be trusted."""

import math

import pytest

from tests.helpers import G, load_benchmark

stiffness_limit = load_benchmark("stiffness_limit")


@pytest.mark.parametrize("turn_factor", [1.0, 2.0])
def test_one_box_tips_where_its_springs_no_longer_carry_its_weight_over_half_its_height(turn_factor):
    """A unit box on four ground springs of (m / 4) omega^2 at +-0.5 m turns back while
    f (m / 4) omega^2 > m g 0.5 (its centre 0.5 m up): omega_crit^2 = 2 g / f."""
    assert stiffness_limit.critical_omega(1, turn_factor) == pytest.approx(math.sqrt(2.0 * G / turn_factor), rel=1e-6)


def test_taller_columns_need_stiffer_springs_and_the_critical_spring_does_not_depend_on_the_mass():
    omegas = [stiffness_limit.critical_omega(n, 1.0) for n in (2, 5, 10, 20)]
    assert omegas == sorted(omegas) and omegas[0] < omegas[-1]
    assert stiffness_limit.column_is_stiff_enough(20, 1.01 * omegas[-1], 1.0, mass=1.0)
    assert not stiffness_limit.column_is_stiff_enough(20, 0.99 * omegas[-1], 1.0, mass=1.0)


def test_no_split_of_the_masses_speeds_a_heavy_on_light_chain_and_the_equal_split_converges():
    """benchmarks/stiffness_limit.py split-weights (docs/method-notes.md, "Limits"): the 1:1000
    chain keeps ~99.98 % of its slowest error per split sweep, and shares that follow the
    partner's mass, or the best of a grid of shares, keep no less."""
    masses = [1.0, 10.0, 100.0, 1000.0]
    equal = stiffness_limit.chain_sweep_radius(masses, stiffness_limit.partner_shares(masses, 0.0))
    assert 0.999 < equal < 1.0
    for power in (0.5, 1.0):
        assert stiffness_limit.chain_sweep_radius(masses, stiffness_limit.partner_shares(masses, power)) >= equal
    best, _ = stiffness_limit.best_grid_shares(masses, steps=13)
    assert best >= equal - 1e-9
    # an equal-mass chain converges ~200x faster per sweep under the same split
    assert stiffness_limit.chain_sweep_radius([1.0] * 4, stiffness_limit.partner_shares([1.0] * 4, 0.0)) < 0.97
