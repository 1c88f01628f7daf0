"""Thrusters: the Blue Robotics T200 thrust curve, a first-order lag and the allocation matrix.

Command u ∈ [−1, 1] is the throttle (PWM − 1500 µs)/400 µs. Positive u pushes the vehicle along the
thruster site's +z axis.
"""

from __future__ import annotations

import csv
import functools
from importlib import resources

import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.errors import UserError

KGF = 9.80665  # N per kgf
SUPPLY_VOLTAGE_RANGE = (10.0, 20.0)  # V, range covered by the bollard data


@struct.dataclass
class T200Curve:
    """The T200 bollard table on its uniform grid, interpolated bilinearly in (voltage, throttle).

    Piecewise-linear interpolation of the measured data keeps its dead band (zero thrust for
    |u| below about 0.07 at 16 V), its forward/reverse asymmetry and its flattening at full
    command, which a deadband + quadratic fit misses by about 2 N at 16 V.
    """

    voltages: jnp.ndarray  # (V,) supply voltages, V, uniformly spaced
    throttles: jnp.ndarray  # (U,) throttle grid in [-1, 1], uniformly spaced
    thrust: jnp.ndarray  # (V, U) bollard thrust, N (positive along the thruster axis)


def load_bollard_table() -> dict[float, np.ndarray]:
    """The shipped Blue Robotics T200 bollard data: {voltage (V): array (n, 2) of [throttle, thrust (N)]}."""
    path = resources.files("marinejax") / "data" / "t200_bollard_10-20V.csv"
    table: dict[float, list] = {}
    with path.open() as f:
        for row in csv.DictReader(f):
            u = (float(row["pwm_us"]) - 1500.0) / 400.0
            table.setdefault(float(row["voltage_V"]), []).append((u, float(row["force_kgf"]) * KGF))
    return {v: np.array(sorted(rows)) for v, rows in sorted(table.items())}


@functools.cache
def _t200_grid() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    table = load_bollard_table()
    voltages = np.array(list(table))
    throttles = table[voltages[0]][:, 0]
    for v, data in table.items():
        if not np.allclose(data[:, 0], throttles):
            raise UserError(f"T200 table: throttle grid at {v} V differs from the one at {voltages[0]} V")
    for name, grid in (("voltage", voltages), ("throttle", throttles)):
        if not np.allclose(np.diff(grid), grid[1] - grid[0]):
            raise UserError(f"T200 table: {name} grid is not uniform")
    return voltages, throttles, np.stack([table[v][:, 1] for v in voltages])


def t200_curve() -> T200Curve:
    """The shipped T200 table (read once per process from the packaged CSV)."""
    v, u, f = _t200_grid()
    return T200Curve(voltages=jnp.asarray(v), throttles=jnp.asarray(u), thrust=jnp.asarray(f))


def _grid_index(x: jnp.ndarray, grid: jnp.ndarray):
    """Lower cell index and fraction of x on a uniform grid (x clipped to the grid)."""
    step = grid[1] - grid[0]
    pos = jnp.clip((x - grid[0]) / step, 0.0, grid.shape[0] - 1.0)
    i = jnp.clip(jnp.floor(pos).astype(jnp.int32), 0, grid.shape[0] - 2)
    return i, pos - i


def t200_thrust(curve: T200Curve, command: jnp.ndarray, voltage: jnp.ndarray) -> jnp.ndarray:
    """Steady bollard thrust (N) of a T200 for throttle `command` ∈ [−1, 1] (clipped) at supply `voltage` (V, 10-20)."""
    iu, fu = _grid_index(jnp.clip(command, -1.0, 1.0), curve.throttles)
    iv, fv = _grid_index(voltage, curve.voltages)
    t = curve.thrust
    lo = t[iv, iu] * (1 - fu) + t[iv, iu + 1] * fu
    hi = t[iv + 1, iu] * (1 - fu) + t[iv + 1, iu + 1] * fu
    return lo * (1 - fv) + hi * fv


def full_thrust(curve: T200Curve, voltage) -> float:
    """The smaller of the full-forward and full-reverse steady thrust (N) of a T200 at `voltage` (V)."""
    return float(np.min(np.abs(np.asarray(t200_thrust(curve, jnp.array([-1.0, 1.0]), jnp.asarray(voltage))))))


def inverse_t200(curve: T200Curve, voltage: float, samples: int = 801):
    """throttle(thrust): the inverse of the steady T200 curve at supply `voltage` (V); thrust in N
    along the thruster axis, throttle in [−1, 1] (±1 beyond the curve, 0 for zero thrust: the dead
    band is skipped). Built once on the host; the returned function is pure JAX."""
    u = np.linspace(-1.0, 1.0, samples)
    f = np.asarray(t200_thrust(curve, jnp.asarray(u), jnp.asarray(voltage)))
    keep = np.abs(f) > 1e-6
    f_grid = np.concatenate([f[keep & (u < 0)], [0.0], f[keep & (u > 0)]])
    u_grid = np.concatenate([u[keep & (u < 0)], [0.0], u[keep & (u > 0)]])
    if np.any(np.diff(f_grid) <= 0):
        raise UserError("the thruster curve is not monotonic; it cannot be inverted")
    f_grid, u_grid = jnp.asarray(f_grid), jnp.asarray(u_grid)
    return lambda thrust: jnp.interp(thrust, f_grid, u_grid, left=-1.0, right=1.0)


def lag_step(thrust: jnp.ndarray, target: jnp.ndarray, dt: float, time_constant: jnp.ndarray) -> jnp.ndarray:
    """Exact first-order lag over dt (s): thrust → target with time constant τ (s); τ = 0 is instantaneous."""
    alpha = 1.0 - jnp.exp(-dt / jnp.maximum(time_constant, 1e-9))
    return thrust + alpha * (target - thrust)


def allocation_matrix(positions: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """6×N matrix B with column i = [e_i; r_i × e_i]; positions r_i (N, 3) m and unit directions e_i (N, 3), body frame."""
    positions = np.asarray(positions, dtype=float)
    directions = np.asarray(directions, dtype=float)
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    return np.concatenate([directions.T, np.cross(positions, directions).T], axis=0)
