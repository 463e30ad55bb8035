"""The 1-D struck-column model of benchmarks/struck_column_model.py (docs/method-notes.md, "A struck
column at 8 iterations"): the findings the light rows' damping ratio rests on, kept true."""

from tests.helpers import load_benchmark

model = load_benchmark("struck_column_model")


def test_the_soft_regime_is_linearly_stable_whatever_the_damping():
    """Every row above its preload: the substep map contracts at zeta 10 and 30 alike (the stability
    argument's condition holds), so what pumps lies outside it."""
    for zeta in (10.0, 30.0):
        assert model.soft_regime_radius(zeta, 8) < 1.0


def test_rigid_rows_below_their_preload_pump_at_8_iterations_unless_damped():
    bouncing, _ = model.struck(10.0, 8)
    resting, depth = model.struck(30.0, 8)
    assert bouncing > 1.0, bouncing  # J in the last second: it never comes to rest
    assert resting < 1e-6 and depth < 0.02, (resting, depth)


def test_rows_soft_below_their_preload_come_to_rest_at_the_plain_damping():
    kinetic, _ = model.struck(10.0, 8, offset=True)
    assert kinetic < 1e-6, kinetic
