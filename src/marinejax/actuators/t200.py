"""The Blue Robotics T200 thruster (actuator kind "t200"): the bollard thrust table, a first-order
lag and the allocation of the thrusts to a body wrench.

Command u ∈ [−1, 1] is the throttle (PWM − 1500 µs)/400 µs. Positive u pushes the vehicle along the
thruster site's +z axis. State: each thruster's thrust (N), lagging its steady value. Settings in
the vehicle file (`marinejax:<prefix>:<field>`): `time_constant` (s, >= 0) and `voltage` (supply, V,
10-20). Episode parameters (`T200Params`): gain per thruster, time constant, voltage.
"""

from __future__ import annotations

import csv
import functools
from importlib import resources

import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.actuators.base import ActuatorKind, allocation_matrix, site_frames
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


@struct.dataclass
class T200Design:
    """What a vehicle file fixes for a group of T200s."""

    allocation: jnp.ndarray  # (6, N) body frame FLU: column i = [e_i; r_i × e_i] (m for the moment arm)
    curve: T200Curve  # steady thrust table


@struct.dataclass
class T200Params:
    """Per-episode parameters of a group of T200s."""

    gain: jnp.ndarray  # (N,) multiplicative thrust scale, 1 = nominal
    time_constant: jnp.ndarray  # () s, first-order lag of the thrust; 0 = instantaneous
    voltage: jnp.ndarray  # () supply voltage, V


class T200(ActuatorKind):
    """Blue Robotics T200 thrusters (see the module docstring)."""

    name = "t200"
    SETTINGS = ("time_constant", "voltage")

    def load(self, m, sites, settings, where):
        self.check_settings(settings, self.SETTINGS, where)
        tc = float(np.asarray(settings.get("time_constant", [np.nan])).reshape(-1)[0])
        volt = float(np.asarray(settings.get("voltage", [np.nan])).reshape(-1)[0])
        if not (np.isfinite(tc) and tc >= 0):
            raise UserError(f"{where}: time_constant must be finite and >= 0 s, got {tc}")
        if not (SUPPLY_VOLTAGE_RANGE[0] <= volt <= SUPPLY_VOLTAGE_RANGE[1]):
            raise UserError(f"{where}: voltage must lie in {SUPPLY_VOLTAGE_RANGE} V, got {volt}")
        positions, rotations = site_frames(m, sites)
        # float32 casts on the host: converting a float64 value to JAX's float32 compiles a program
        design = T200Design(allocation=jnp.asarray(np.float32(allocation_matrix(positions, rotations[:, :, 2]))),
                            curve=t200_curve())
        params = T200Params(gain=jnp.asarray(np.ones(len(sites), np.float32)),
                            time_constant=jnp.asarray(np.float32(tc)), voltage=jnp.asarray(np.float32(volt)))
        return design, params

    def target(self, design, params, command):
        return params.gain * t200_thrust(design.curve, command, params.voltage)

    def wrench(self, design, params, state, nu_r):
        return design.allocation @ state

    def describe(self, names, params):
        return f"T200 throttle per thruster in [-1, 1] ((PWM - 1500 us)/400 us; positive pushes along the site's +z), order {list(names)}"

    def state_range(self, design, params):
        thrust = np.asarray(self.target(design, params, -1.0)), np.asarray(self.target(design, params, 1.0))
        return tuple(np.broadcast_to(t, params.gain.shape) for t in thrust)

    def randomize(self, params, draw, config):
        return params.replace(
            gain=params.gain * draw(config.thruster_gain, params.gain.shape),
            time_constant=draw(config.thruster_time_constant, ()),
            voltage=draw(config.voltage, ()),
        )

    file_fields = ("thruster_gain", "thruster_time_constant")

    def from_file(self, params, values):
        if "thruster_gain" in values:
            params = params.replace(gain=jnp.asarray(np.full(params.gain.shape, values["thruster_gain"], np.float32)))
        if "thruster_time_constant" in values:
            params = params.replace(time_constant=jnp.asarray(np.float32(values["thruster_time_constant"])))
        return params

    def privileged(self, params):
        return jnp.concatenate([params.gain, params.time_constant[None], params.voltage[None]])


def only_t200(groups, what: str):
    """The single actuator group of a vehicle driven only by T200s; `what` (e.g. "the PID
    controller") needs one and is named in the UserError otherwise."""
    if len(groups) != 1 or not isinstance(groups[0].kind, T200):
        kinds = [g.kind.name for g in groups]
        raise UserError(f"{what} needs a vehicle driven by one group of T200 thrusters; this one has actuator kinds {kinds}")
    return groups[0]
