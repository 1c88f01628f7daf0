"""T200 thrust table, lag and allocation against the published data (vehicles reference)."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.frames import FRD_TO_FLU
from marinejax.actuators.base import allocation_matrix, lag_step
from marinejax.actuators.t200 import load_bollard_table, t200_curve, t200_thrust

# BlueROV2 Heavy geometry, FRD, von Benzon et al. 2022 (J. Mar. Sci. Eng. 10(12):1898).
HEAVY_POS_FRD = [(0.156, 0.111, 0.085), (0.156, -0.111, 0.085), (-0.156, 0.111, 0.085), (-0.156, -0.111, 0.085),
                 (0.12, 0.218, 0), (0.12, -0.218, 0), (-0.12, 0.218, 0), (-0.12, -0.218, 0)]
HEAVY_DIR_FRD = [(0.707, -0.707, 0), (0.707, 0.707, 0), (-0.707, -0.707, 0), (-0.707, 0.707, 0)] + [(0, 0, -1)] * 4


@pytest.fixture(scope="module")
def curve():
    return t200_curve()


@pytest.mark.parametrize("voltage,forward,reverse", [(12, 36.4, -28.5), (16, 51.4, -39.9), (20, 65.9, -49.4)])
def test_full_command_thrust_matches_bollard_data(curve, voltage, forward, reverse):
    """Full forward / reverse thrust (N) from the Blue Robotics T200 data, Sept. 2019."""
    assert float(t200_thrust(curve, jnp.float32(1.0), jnp.float32(voltage))) == pytest.approx(forward, abs=1.0)
    assert float(t200_thrust(curve, jnp.float32(-1.0), jnp.float32(voltage))) == pytest.approx(reverse, abs=1.0)


def test_table_reproduces_every_16v_sample(curve):
    data = load_bollard_table()[16.0]
    pred = np.asarray(t200_thrust(curve, jnp.asarray(data[:, 0], jnp.float32), jnp.float32(16.0)))
    assert np.max(np.abs(pred - data[:, 1])) < 0.01


def test_dead_band_and_asymmetry(curve):
    u = jnp.array([-0.06, -0.02, 0.0, 0.02, 0.06])
    np.testing.assert_array_equal(np.asarray(t200_thrust(curve, u, jnp.float32(16.0))), 0.0)  # 1472-1528 µs
    f = np.asarray(t200_thrust(curve, jnp.array([0.5, -0.5, 1.0, -1.0]), jnp.float32(16.0)))
    assert f[0] > -f[1] and f[2] > -f[3]  # forward is stronger
    assert f[0] > 0 > f[1]


def test_voltage_interpolates_between_tables(curve):
    f14, f15, f16 = (float(t200_thrust(curve, jnp.float32(1.0), jnp.float32(v))) for v in (14, 15, 16))
    assert f14 < f15 < f16
    assert f15 == pytest.approx((f14 + f16) / 2, rel=1e-5)


def test_commands_beyond_one_are_clipped(curve):
    assert float(t200_thrust(curve, jnp.float32(3.0), jnp.float32(16.0))) == float(t200_thrust(curve, jnp.float32(1.0), jnp.float32(16.0)))


def test_lag_is_exact_first_order():
    f = lag_step(jnp.float32(0.0), jnp.float32(10.0), 0.01, jnp.float32(0.05))
    assert float(f) == pytest.approx(10 * (1 - math.exp(-0.2)), rel=1e-6)
    assert float(lag_step(jnp.float32(0.0), jnp.float32(10.0), 0.01, jnp.float32(0.0))) == 10.0  # τ = 0


def test_heavy_allocation_matches_published_geometry():
    v = mj.load_vehicle("bluerov2_heavy")
    ours_flu = np.asarray(v.sys.actuators[0].design.allocation, dtype=np.float64)
    # The same matrix expressed in FRD: forces and moments both flip y and z.
    to_frd = np.kron(np.eye(2), FRD_TO_FLU)
    ours_frd = to_frd @ ours_flu
    published = allocation_matrix(np.array(HEAVY_POS_FRD), np.array(HEAVY_DIR_FRD))
    np.testing.assert_allclose(ours_frd, published, atol=2e-3)
    # Wu 2018's matrix entries, up to the sign of individual thrusters (propeller handedness):
    a = np.abs(ours_frd)
    np.testing.assert_allclose(a[0, :4], 0.7071, atol=1e-3)
    np.testing.assert_allclose(a[3, :4], 0.0601, atol=1e-3)
    np.testing.assert_allclose(a[3, 4:], 0.218, atol=1e-3)
    np.testing.assert_allclose(a[4, :4], 0.0601, atol=1e-3)
    np.testing.assert_allclose(a[4, 4:], 0.12, atol=1e-3)
    np.testing.assert_allclose(a[5, :4], 0.1888, atol=1e-3)
    assert np.linalg.matrix_rank(ours_flu) == 6


def test_bluerov2_has_six_thrusters_and_no_pitch_authority():
    v = mj.load_vehicle("bluerov2")
    b = np.asarray(v.sys.actuators[0].design.allocation)
    assert b.shape == (6, 6)
    assert np.linalg.matrix_rank(b, tol=1e-6) == 5
    np.testing.assert_allclose(b[4], 0.0, atol=1e-6)  # pitch row: no thruster makes a pitch moment
