"""System identification: fit a vehicle's fluid and thruster parameters to a logged run.

Log format (CSV, one row per control step at a constant period; `read_log`, `write_log`):
  time_s                                  s since the start
  u1 .. uN                                throttle per thruster in [−1, 1], the vehicle's thruster order,
                                          applied from this row's time to the next row's
  qw, qx, qy, qz                          attitude, body → world (world z up, body FLU)
  vx_mps, vy_mps, vz_mps                  body-frame velocity over ground (a DVL gives it), m/s
  wx_radps, wy_radps, wz_radps            body-frame angular velocity (the gyro), rad/s
  x_m, y_m, z_m                           optional world position (z up), m
  dvl_valid                               optional, 1 or 0: 0 where the DVL gave no new measurement
                                          (between its updates, dropouts) and the row holds an older
                                          velocity; such rows are left out of the velocity residuals
A vehicle in ArduSub logs this from its thruster outputs, the AHRS attitude, the DVL and the gyro.
`simulate_log` makes such a log from a parameter set, measured by the plant's sensor models
(`plant.sensors`: gyro bias and noise, attitude-estimate noise, a 10 Hz DVL with dropouts, a late
position fix).

`excitation(vehicle)` makes a command sequence that moves each degree of freedom in turn and then
all of them (piecewise-constant random levels in wrench space, held 0.5–2 s, within `amplitude` of
the smallest full thrust), allocated to the thrusters; `marinejax excite` writes it as a log with
only time and commands, for a user to run on their vehicle.

`identify(log, vehicle)` fits added mass (6), linear and quadratic damping (6 + 6), displaced
volume, centre of buoyancy (3), one thruster gain for all thrusters and the thruster time constant
(the thruster gain only on request, see below) by multiple shooting: the log is cut into windows of
`window` seconds, each starting on a row with a DVL measurement; each is simulated from its start
state with the logged commands by the same differentiable plant the envs use. The residuals are the
simulated minus logged body velocities (rows with a new DVL measurement only), angular velocities,
roll and pitch, each divided by its measurement noise. A window's start state (velocity, angular
velocity, roll, pitch) is a measurement too, so it is fitted as well, held to the measured start by
a prior of the same noise: starting from the noisy measurement itself biases the damping (errors in
the variables). Short windows keep the rollouts from diverging, so long logs and weakly stable
directions do not blow up the fit. The optimiser is Levenberg–Marquardt on the Jacobian that JAX
gives through the rollout (24 parameters plus 8 per window; the windows' starts are eliminated
from each step by the Schur complement, as in bundle adjustment; faster and more precise here than
first-order methods such as optax's Adam), with every parameter kept within physical bounds. The
fit runs twice: on windows of half the length from the defaults, then on `window` from there
(shorter windows are closer to linear in the parameters, which keeps a start far from the truth out
of local minima; `Identifier.fit`). Uncertainty: the Gauss–Newton covariance σ² (Schur
complement)⁻¹ at the optimum, σ² the mean squared normalised residual; a parameter whose standard
deviation exceeds 10 % of its scale is reported as not determined by the log (relative to the
larger of its value and its scale).

What a log cannot determine: scaling every force (thrust, damping, buoyancy moment) and the total
mass (rigid + added) by one factor leaves the motion unchanged, with the displaced volume absorbing
the weight difference; the rigid mass (weighed) does not pin it because the added mass is free. So
the thrust scale and the masses are not separately identifiable from motion alone: the thruster
gain stays at its value (the T200 bollard curve, which was measured on a load cell) unless
`fit_thruster_gain=True`, and then the report shows it and the masses as undetermined. Which
manoeuvre determines what: steps in each axis alone give that axis's added mass (the acceleration
after a thrust step) and damping (the terminal speed: linear from small, quadratic from large
levels); roll and pitch motions give the centre of buoyancy (restoring moment) and the displaced
volume comes from the heave offset; command changes give the thruster time constant.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import time as _time
from pathlib import Path
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from marinejax.errors import MissingFileError, UserError
from marinejax.frames import quat_from_euler, quat_to_euler
from marinejax.physics import VehicleState
from marinejax.plant import Plant, PlantParams
from marinejax.actuators.base import lag_step
from marinejax.actuators.t200 import full_thrust, inverse_t200, only_t200, t200_thrust


@dataclasses.dataclass(frozen=True)
class Log:
    """One logged run (see the module docstring for units and frames); arrays with T rows."""

    time: np.ndarray  # (T,) s
    commands: np.ndarray  # (T, N) throttles
    quaternion: np.ndarray | None = None  # (T, 4)
    velocity: np.ndarray | None = None  # (T, 3) m/s, body
    angular_velocity: np.ndarray | None = None  # (T, 3) rad/s, body
    position: np.ndarray | None = None  # (T, 3) m, world
    dvl_valid: np.ndarray | None = None  # (T,) bool: the row's velocity is a new DVL measurement

    @property
    def dt(self) -> float:
        return float(np.median(np.diff(self.time)))


_STATE_COLUMNS = {
    "quaternion": ("qw", "qx", "qy", "qz"),
    "velocity": ("vx_mps", "vy_mps", "vz_mps"),
    "angular_velocity": ("wx_radps", "wy_radps", "wz_radps"),
    "position": ("x_m", "y_m", "z_m"),
}


def write_log(path: Path | str, log: Log) -> Path:
    path = Path(path)
    n = log.commands.shape[1]
    columns = {"time_s": log.time[:, None], **{f"u{i + 1}": log.commands[:, i : i + 1] for i in range(n)}}
    for field, names in _STATE_COLUMNS.items():
        values = getattr(log, field)
        if values is not None:
            columns.update({name: values[:, i : i + 1] for i, name in enumerate(names)})
    if log.dvl_valid is not None:
        columns["dvl_valid"] = log.dvl_valid.astype(float)[:, None]
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(list(columns))
        for row in np.concatenate(list(columns.values()), axis=1):
            writer.writerow([f"{v:.7g}" for v in row])
    return path


def read_log(path: Path | str, num_thrusters: int) -> Log:
    """A log from CSV; raises UserError naming what is missing or malformed."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"log file not found: {path}")
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if len(rows) < 3:
        raise UserError(f"{path}: a log needs a header and at least two rows")
    header = rows[0]
    try:
        data = np.array(rows[1:], dtype=float)
    except ValueError as err:
        raise UserError(f"{path}: every value must be a number ({err})") from None
    col = {name: i for i, name in enumerate(header)}
    needed = ["time_s"] + [f"u{i + 1}" for i in range(num_thrusters)]
    missing = [c for c in needed if c not in col]
    if missing:
        raise UserError(f"{path}: missing columns {missing}; a log has time_s, u1..u{num_thrusters} and the measured "
                        f"columns {[c for cs in _STATE_COLUMNS.values() for c in cs]}")
    if not np.all(np.isfinite(data)):
        raise UserError(f"{path}: the log contains non-finite values")
    fields = {}
    for field, names in _STATE_COLUMNS.items():
        if all(n in col for n in names):
            fields[field] = data[:, [col[n] for n in names]]
    if "dvl_valid" in col:
        valid = data[:, col["dvl_valid"]]
        if not np.all((valid == 0) | (valid == 1)):
            raise UserError(f"{path}: dvl_valid must be 0 or 1, got {sorted(set(valid[(valid != 0) & (valid != 1)].tolist()))[:5]}")
        if valid.sum() < 2:
            raise UserError(f"{path}: dvl_valid marks fewer than two rows as valid")
        fields["dvl_valid"] = valid.astype(bool)
    log = Log(time=data[:, col["time_s"]], commands=data[:, [col[c] for c in needed[1:]]], **fields)
    if np.any(np.diff(log.time) <= 0):
        raise UserError(f"{path}: time_s must increase")
    return log


def excitation(plant: Plant, duration: float = 120.0, amplitude: float = 0.5, seed: int = 0) -> np.ndarray:
    """Commands (T, N) at the plant's control period: each degree of freedom alone for duration/8, then
    all together for the remaining quarter; levels uniform in ±amplitude · (smallest full thrust) per
    thruster-equivalent, held 0.5–2 s."""
    if not 0 < amplitude <= 1:
        raise UserError(f"--amplitude must be in (0, 1], got {amplitude}")
    if not duration >= 10:
        raise UserError(f"--duration must be at least 10 s, got {duration}")
    dt = plant.config.control_dt
    steps = int(round(duration / dt))
    rng = np.random.default_rng(seed)
    group = only_t200(plant.sys.actuators, "the excitation")
    params = plant.nominal_params().actuators[0]
    curve = group.design.curve
    full = full_thrust(curve, params.voltage)
    alloc = np.asarray(group.design.allocation)
    pinv = np.linalg.pinv(alloc)
    # the largest wrench per axis that keeps every thruster within `amplitude` of full thrust
    axis_max = np.array([amplitude * full / max(np.abs(pinv[:, k]).max(), 1e-9) for k in range(6)])
    controllable = np.linalg.norm(alloc @ pinv - np.eye(6), axis=0) < 1e-6
    wrench = np.zeros((steps, 6))
    segment = steps // 8
    t = 0
    for k in range(6):
        end = (k + 1) * segment
        while t < end:
            hold = int(rng.uniform(0.5, 2.0) / dt)
            if controllable[k]:
                wrench[t : min(t + hold, end), k] = rng.uniform(-1, 1) * axis_max[k]
            t += hold
        t = end
    while t < steps:
        hold = int(rng.uniform(0.5, 2.0) / dt)
        wrench[t : t + hold] = rng.uniform(-1, 1, 6) * axis_max * controllable / 2
        t += hold
    throttle = inverse_t200(curve, float(params.voltage))
    return np.clip(np.asarray(throttle(jnp.asarray(wrench @ pinv.T))), -1.0, 1.0)


# --- the fitted parameters -------------------------------------------------------------------
# name, size, scale (the unit of the normalised parameter), lower bound
_FIT = (
    ("added_mass", 6, np.array([5, 5, 5, 0.1, 0.1, 0.1]), 0.0),
    ("linear_damping", 6, np.array([5, 5, 5, 0.5, 0.5, 0.5]), 0.0),
    ("quadratic_damping", 6, np.array([50, 50, 50, 1, 1, 1]), 0.0),
    ("volume", 1, np.array([1e-3]), 1e-4),
    ("center_of_buoyancy", 3, np.array([0.01, 0.01, 0.01]), -np.inf),
    ("thruster_gain", 1, np.array([0.1]), 0.1),
    ("time_constant", 1, np.array([0.02]), 0.0),
)
PARAMETER_NAMES = tuple(f"{name}[{i}]" if size > 1 else name for name, size, _, _ in _FIT for i in range(size))


def _flatten(params: PlantParams) -> np.ndarray:
    h = params.hydro
    values = {"added_mass": h.added_mass, "linear_damping": h.linear_damping, "quadratic_damping": h.quadratic_damping,
              "volume": h.volume, "center_of_buoyancy": h.center_of_buoyancy,
              "thruster_gain": jnp.mean(params.actuators[0].gain), "time_constant": params.actuators[0].time_constant}
    return np.concatenate([np.atleast_1d(np.asarray(values[name], float)) for name, *_ in _FIT])


def _unflatten(base: PlantParams, x: jnp.ndarray) -> PlantParams:
    out, i = {}, 0
    for name, size, _, _ in _FIT:
        out[name] = x[i : i + size] if size > 1 else x[i]
        i += size
    hydro = base.hydro.replace(added_mass=out["added_mass"], linear_damping=out["linear_damping"],
                               quadratic_damping=out["quadratic_damping"], volume=out["volume"],
                               center_of_buoyancy=out["center_of_buoyancy"])
    (t200,) = base.actuators
    t200 = t200.replace(gain=jnp.full_like(t200.gain, out["thruster_gain"]), time_constant=out["time_constant"])
    return base.replace(hydro=hydro, actuators=(t200,))


_SCALE = np.concatenate([s for _, _, s, _ in _FIT])
_LOWER = np.concatenate([np.full(n, lo) for _, n, _, lo in _FIT])


WINDOW_BATCH = 32  # windows simulated together (see Identifier.simulate)

# Measurement noise per residual channel (body velocity 3 m/s, angular velocity 3 rad/s, roll and
# pitch rad): the sensor models' size (DVL at 0.5 m/s, gyro, attitude estimate).
_NOISE = np.array([0.006] * 3 + [0.002] * 3 + [0.0035] * 2)


@dataclasses.dataclass(frozen=True)
class FitResult:
    params: PlantParams
    names: tuple[str, ...]
    initial: np.ndarray  # (24,) values before the fit
    values: np.ndarray  # (24,) fitted values
    std: np.ndarray  # (24,) standard deviations (Gauss–Newton; 0 for a parameter held fixed)
    determined: np.ndarray  # (24,) bool: std below 10 % of the larger of |value| and the parameter's scale
    fitted: np.ndarray  # (24,) bool: False for a parameter held at its value
    cost_before: float  # mean squared normalised residual
    cost_after: float
    seconds: float
    warning: str = ""  # why the fit or its uncertainty is incomplete (a singular system), else ""
    steps: int = 0  # Levenberg–Marquardt steps that lowered the cost


class Identifier:
    """Multiple-shooting residuals of a log for one vehicle; jitted once per (log length, window)."""

    def __init__(self, plant: Plant, log: Log, window: float = 1.0, fit_thruster_gain: bool = False):
        if log.quaternion is None or log.velocity is None or log.angular_velocity is None:
            raise UserError("identification needs the attitude (qw..qz), body velocity (vx_mps..) and angular velocity (wx_radps..) columns")
        only_t200(plant.sys.actuators, "identification")
        if log.commands.shape[1] != plant.vehicle.num_actuators:
            raise UserError(f"the log has {log.commands.shape[1]} thruster columns; vehicle {plant.vehicle.name!r} has {plant.vehicle.num_actuators}")
        if abs(log.dt - plant.config.control_dt) > 1e-3 * plant.config.control_dt:
            raise UserError(f"the log's period {log.dt:.4f} s differs from the control period {plant.config.control_dt} s; "
                            "resample the log or pass --env control_dt=...")
        self.plant, self.log, self.window, self.fit_thruster_gain = plant, log, window, fit_thruster_gain
        self.steps = max(2, int(round(window / plant.config.control_dt)))
        valid = np.ones(len(log.time), bool) if log.dvl_valid is None else np.asarray(log.dvl_valid, bool)
        # windows start on rows with a DVL measurement (a row without one holds an older velocity)
        starts, row = [], 0
        while row + self.steps < len(log.time):
            if valid[row]:
                starts.append(row)
                row += self.steps
            else:
                row += 1
        starts = np.asarray(starts, int)
        n = len(starts)
        if n < 4:
            raise UserError(f"the log is too short: {len(log.time)} rows give {n} windows of {window} s (need at least 4)")
        idx = starts[:, None] + np.arange(1, self.steps + 1)[None]
        q = log.quaternion / np.linalg.norm(log.quaternion, axis=1, keepdims=True)
        euler = np.asarray(jax.vmap(quat_to_euler)(jnp.asarray(q)))
        self.start_euler = jnp.asarray(euler[starts])
        self.start = VehicleState(position=jnp.zeros((n, 3)), quaternion=jnp.asarray(q[starts]),
                                  velocity=jnp.asarray(log.velocity[starts]), angular_velocity=jnp.asarray(log.angular_velocity[starts]),
                                  actuators=jnp.zeros((n, plant.vehicle.num_actuators)))
        self.all_commands = jnp.asarray(log.commands)
        self.start_rows = jnp.asarray(starts)
        self.commands = jnp.asarray(log.commands[idx - 1])  # the command of row k acts from row k to k + 1
        self.target = jnp.asarray(np.concatenate([log.velocity[idx], log.angular_velocity[idx], euler[idx][..., :2]], axis=-1))
        # residual weights: 0 for the velocity of a row without a new DVL measurement
        weight = np.ones(self.target.shape)
        weight[..., :3] = valid[idx][..., None]
        self.weight = jnp.asarray(weight)
        self.count = float(weight.sum())
        self.noise = jnp.asarray(_NOISE)
        self.base = plant.nominal_params()
        self.x0 = _flatten(self.base)
        self.free = np.array([fit_thruster_gain or n != "thruster_gain" for n in PARAMETER_NAMES])
        self.residuals = jax.jit(self._residuals)
        self.linearize = jax.jit(self._linearize)

    def simulate(self, params: PlantParams, offset: jnp.ndarray | None = None) -> jnp.ndarray:
        """(windows, steps, 8): body velocity, angular velocity, roll, pitch simulated from each
        window's start; `offset` (windows, 8) is added to the start's velocity, angular velocity,
        roll and pitch (the fitted correction of the measured start)."""
        plant, key = self.plant, jax.random.PRNGKey(0)
        # the thrusters' lag state at each window start: the lag filter run over the whole command
        # history from rest (it does not depend on the rigid-body motion)
        curve, dt = plant.sys.actuators[0].design.curve, plant.config.control_dt / plant.config.substeps
        t200 = params.actuators[0]

        def lag(thrust, u):
            target = t200_thrust(curve, u, t200.voltage) * t200.gain
            for _ in range(plant.config.substeps):
                thrust = lag_step(thrust, target, dt, t200.time_constant)
            return thrust, thrust

        _, history = jax.lax.scan(lag, jnp.zeros(self.all_commands.shape[1]), self.all_commands)
        history = jnp.concatenate([jnp.zeros((1, history.shape[1])), history])  # thrust at row k

        def window(start, euler, offset, thrust, commands):
            quaternion = quat_from_euler(euler[0] + offset[6], euler[1] + offset[7], euler[2])
            start = start.replace(velocity=start.velocity + offset[:3], angular_velocity=start.angular_velocity + offset[3:6],
                                  quaternion=quaternion, actuators=thrust)
            state = plant.init(key, params, start)
            vs = plant.open_loop(params, state, commands, key)[1]
            euler = jax.vmap(quat_to_euler)(vs.quaternion)[:, :2]
            return jnp.concatenate([vs.velocity, vs.angular_velocity, euler], axis=-1)

        n = len(self.start_rows)
        if offset is None:
            offset = jnp.zeros((n, 8))
        # windows in batches: one vmap over every window of a long log (thousands of rollouts with
        # their tangents) hangs XLA's CPU runtime (jax 0.10.2). Padded to whole batches with copies
        # of the last window, dropped from the result: lax.map would trace the rollout a second time
        # for a last, partial batch, and compiling it twice was most of a fit's time.
        pad = -n % WINDOW_BATCH
        xs = jax.tree.map(lambda a: jnp.concatenate([a, jnp.repeat(a[-1:], pad, axis=0)]),
                          (self.start, self.start_euler, offset, history[self.start_rows], self.commands))
        return jax.lax.map(lambda args: window(*args), xs, batch_size=WINDOW_BATCH)[:n]

    def _residuals(self, z: jnp.ndarray, offset: jnp.ndarray) -> jnp.ndarray:
        """(windows, steps · 8) normalised residuals; z: normalised parameters, offset: (windows, 8)."""
        x = jnp.asarray(self.x0) + z * jnp.asarray(_SCALE, jnp.float32)
        d = self.simulate(_unflatten(self.base, x), offset) - self.target
        d = d.at[..., 6:].set(jnp.arctan2(jnp.sin(d[..., 6:]), jnp.cos(d[..., 6:])))  # roll/pitch across ±π
        return (d * self.weight / self.noise).reshape(d.shape[0], -1)

    def _linearize(self, z: jnp.ndarray, offset: jnp.ndarray):
        """Residuals with their Jacobians in z (windows, rows, 24) and in each window's own start
        offset (windows, rows, 8). A window depends only on its own start, so shifting every
        window's offset at once gives every block in 8 directional derivatives; all 32 directions
        go through one forward-mode pass (one rollout to compile, not three)."""
        n = z.shape[0]

        def shifted(v):
            r = self._residuals(z + v[:n], offset + v[n:][None])
            return r, r

        jac, r = jax.jacfwd(shifted, has_aux=True)(jnp.zeros(n + 8, z.dtype))
        return r, jac[..., :n], jac[..., n:]

    def fit(self, iterations: int = 30, progress: Callable[[str], None] | None = None, coarse: bool = True,
            start: np.ndarray | None = None, tolerance: float = 1e-6) -> FitResult:
        """Levenberg–Marquardt over the parameters and every window's start correction (each held to
        its measurement by a prior of the measurement noise), the starts eliminated per step (Schur
        complement); the parameters' covariance accounts for the starts' uncertainty.

        `coarse`: first fit windows of half the length from the defaults, then these windows from
        there (and, should that stall, also from the defaults, keeping the lower cost). Shorter
        windows keep the residuals closer to linear in the parameters: from the defaults, 1 s
        windows alone stopped in a local minimum (a linear damping at its zero bound, the quadratic
        one too large) on a third of the Wu 2018 logs tried (docs/identification.md).
        `start`: parameter values (24,) to start from (default: the plant's); `cost_before` is
        always the defaults' cost. The fit stops when a step lowers the cost by less than
        `tolerance` times it (the first of two stages at 1e-3: it only has to reach the basin the
        second refines)."""
        t0 = _time.perf_counter()
        if coarse and start is None:
            first = Identifier(self.plant, self.log, self.window / 2, self.fit_thruster_gain)
            if first.steps < self.steps:
                coarse_fit = first.fit(iterations, _prefixed(progress, first.window), coarse=False, tolerance=1e-3)
                staged = self.fit(iterations, _prefixed(progress, self.window), coarse=False, start=coarse_fit.values)
                if staged.steps == 0:
                    # stalled there (a few windows whose rollouts leave their measured starts within
                    # the longer window stopped the first step on one log): the longer windows from
                    # the defaults too, and the better of the two
                    plain = self.fit(iterations, _prefixed(progress, self.window, "from the defaults"), coarse=False)
                    staged = min((staged, plain), key=lambda r: r.cost_after)
                return dataclasses.replace(staged, seconds=_time.perf_counter() - t0)
        lower = (_LOWER - self.x0) / _SCALE  # bounds on z
        free = self.free
        z, offset = np.zeros(len(self.x0)), np.zeros((len(self.start_rows), 8))
        prior = 1.0 / np.asarray(self.noise, float)  # a start correction's prior residual: offset / noise

        def evaluate(z, offset):
            r = np.asarray(self.residuals(jnp.asarray(z, jnp.float32), jnp.asarray(offset, jnp.float32)), float)
            total = float(np.sum(r**2) + np.sum((offset * prior) ** 2))
            return total / self.count if np.isfinite(total) else np.inf

        def normal_equations(z, offset):
            r, jz, js = (np.asarray(a, float) for a in self.linearize(jnp.asarray(z, jnp.float32), jnp.asarray(offset, jnp.float32)))
            a_mat, g = np.einsum("wri,wrj->ij", jz, jz), np.einsum("wri,wr->i", jz, r)
            b_mat = np.einsum("wri,wrj->wij", js, js) + np.diag(prior**2)
            gs = np.einsum("wri,wr->wi", js, r) + offset * prior**2
            return a_mat, g, b_mat, gs, np.einsum("wri,wrj->wij", jz, js)

        steps = 0
        cost0 = cost = evaluate(z, offset)
        if start is not None:
            z = np.where(free, (np.asarray(start, float) - self.x0) / _SCALE, 0.0)
            cost = evaluate(z, offset)
        lam = 1e-2
        for it in range(iterations):
            a_mat, g, b_mat, gs, e_mat = normal_equations(z, offset)
            # a parameter at its bound that the gradient pushes further out stays there this step
            # (projecting the full step instead stalls the fit)
            active = free & ~((z <= lower + 1e-9) & (g > 0))
            a_act, e_act = a_mat[np.ix_(active, active)], e_mat[:, active]
            improvement = 0.0
            while lam <= 1e8:
                try:
                    b_inv = np.linalg.inv(b_mat * (1 + lam * np.eye(8)))
                    reduced = a_act + lam * np.diag(np.diag(a_act) + 1e-9) - np.einsum("wij,wjk,wlk->il", e_act, b_inv, e_act)
                    step = np.zeros_like(z)
                    step[active] = -np.linalg.solve(reduced, g[active] - np.einsum("wij,wjk,wk->i", e_act, b_inv, gs))
                except np.linalg.LinAlgError:  # singular at this damping: damp more
                    lam *= 4
                    continue
                z_new = np.maximum(z + step, lower)
                offset_new = offset - np.einsum("wij,wj->wi", b_inv, gs + np.einsum("wij,i->wj", e_mat, z_new - z))
                cost_new = evaluate(z_new, offset_new)
                if cost_new < cost:
                    improvement = cost - cost_new
                    z, offset, cost, lam, steps = z_new, offset_new, cost_new, max(lam / 3, 1e-7), steps + 1
                    break
                lam *= 4
            if progress is not None:
                progress(f"iteration {it + 1:2d}: cost {cost:.4g} (mean squared residual / noise²)")
            if lam > 1e8 or improvement < tolerance * cost:
                break
        # covariance of the parameters, the starts eliminated: σ² (Schur complement)⁻¹
        warning = ""
        std_z = np.zeros(len(z))
        try:
            a_mat, _, b_mat, _, e_mat = normal_equations(z, offset)
            e_free = e_mat[:, free]
            info = a_mat[np.ix_(free, free)] - np.einsum("wij,wjk,wlk->il", e_free, np.linalg.inv(b_mat), e_free)
            std_z[free] = np.sqrt(np.maximum(np.diag(np.linalg.pinv(info) * cost), 0))
        except (np.linalg.LinAlgError, FloatingPointError) as err:  # the values stand; their uncertainty is unknown
            std_z[free] = np.nan
            warning = f"no uncertainty: the covariance at the fitted values could not be computed ({err})"
        values = self.x0 + z * _SCALE
        std = std_z * _SCALE
        return FitResult(params=_unflatten(self.base, jnp.asarray(values, jnp.float32)), names=PARAMETER_NAMES,
                         initial=self.x0, values=values, std=std, determined=std < 0.1 * np.maximum(np.abs(values), _SCALE),
                         fitted=free.copy(), cost_before=cost0, cost_after=cost, seconds=_time.perf_counter() - t0, warning=warning,
                         steps=steps)


def _prefixed(progress: Callable[[str], None] | None, window: float, note: str = "") -> Callable[[str], None] | None:
    """`progress` with each line prefixed by the window length (and `note`)."""
    if progress is None:
        return None
    prefix = f"{window:g} s windows{', ' + note if note else ''}, "
    return lambda line: progress(prefix + line)


def simulate_log(plant: Plant, params: PlantParams, commands: np.ndarray, seed: int = 0, noise: bool = True,
                 start: VehicleState | None = None) -> Log:
    """A synthetic log: `commands` (T, N) run on `params` from rest at 5 m depth (or `start`); T + 1
    rows. Measured by the plant's sensor models (`plant.config.sensors`): the attitude estimate, the
    gyro (turn-on bias, walk, noise), the DVL (its rate; rows between updates and dropouts hold the
    last value, dvl_valid 0) and the position fix (its rate and latency). `noise=False` logs the
    exact state at every row."""
    key = jax.random.PRNGKey(seed)
    if start is None:
        from marinejax.physics import initial_state

        start = initial_state(plant.vehicle, position=(0.0, 0.0, -5.0))
    sensors = plant.sensors

    @jax.jit
    def run(commands):
        k_run, k_params, k_init, k_measure = jax.random.split(key, 4)
        _, states, finite = plant.open_loop(params, plant.init(k_run, params, start), commands, k_run)
        states = jax.tree.map(lambda a0, a: jnp.concatenate([a0[None], a]), start, states)
        if not noise:
            return states, None, finite
        sensor_state, first = sensors.init(k_init, sensors.sample_params(k_params), start)

        def measure(sensor_state, xs):
            return sensors.step(sensor_state, *xs)

        _, rest = jax.lax.scan(measure, sensor_state, (jax.tree.map(lambda a: a[1:], states),
                                                       jax.random.split(k_measure, commands.shape[0])))
        measured = jax.tree.map(lambda a0, a: jnp.concatenate([a0[None], a]), first, rest)
        return states, measured, finite

    states, measured, finite = jax.tree.map(np.asarray, run(jnp.asarray(commands, jnp.float32)))
    if not np.all(finite):
        raise FloatingPointError("the simulated log went non-finite")
    time = plant.config.control_dt * np.arange(len(commands) + 1)
    commands = np.concatenate([commands, commands[-1:]])
    if not noise:
        return Log(time=time, commands=commands, quaternion=states.quaternion.astype(float),
                   velocity=states.velocity.astype(float), angular_velocity=states.angular_velocity.astype(float),
                   position=states.position.astype(float))
    return Log(time=time, commands=commands, quaternion=measured.quaternion.astype(float),
               velocity=measured.dvl.astype(float), angular_velocity=measured.gyro.astype(float),
               position=measured.fix.astype(float), dvl_valid=measured.dvl_new.astype(bool))


def save_param_set(path: Path | str, vehicle: str, result: FitResult, source: str) -> Path:
    """Write the fitted parameters as a parameter-set file for `load_vehicle(name, param_set=path)`
    and every env (`--env param_set=PATH`)."""
    p = result.params
    data = {
        "vehicle": vehicle, "source": source,
        "added_mass": np.asarray(p.hydro.added_mass_matrix() if not p.hydro.simple else p.hydro.added_mass).reshape(-1).tolist(), "linear_damping": np.asarray(p.hydro.linear_damping).tolist(),
        "quadratic_damping": np.asarray(p.hydro.quadratic_damping).tolist(), "volume": float(p.hydro.volume),
        "fluid_density": float(p.hydro.fluid_density), "center_of_buoyancy": np.asarray(p.hydro.center_of_buoyancy).tolist(),
        "mass": float(p.mass), "inertia": np.asarray(p.inertia).tolist(),
        "thruster_gain": float(np.mean(np.asarray(p.actuators[0].gain))), "thruster_time_constant": float(p.actuators[0].time_constant),
        "fit": {n: {"value": float(v), "std": float(s) if np.isfinite(s) else None, "determined": bool(d)}
                for n, v, s, d in zip(result.names, result.values, result.std, result.determined)},
    }
    path = Path(path)
    path.write_text(json.dumps(data, indent=2))
    return path


def prediction_error(plant: Plant, params: PlantParams, log: Log, window: float = 1.0) -> float:
    """RMS (m/s) of the body velocity predicted over `window`-second windows of `log` from each
    window's logged start, with `params`, against the logged velocity."""
    ident = Identifier(plant, log, window)
    error = (np.asarray(ident.simulate(params)) - np.asarray(ident.target))[..., :3]
    weight = np.asarray(ident.weight)[..., :3]
    return float(np.sqrt(np.sum(weight * error**2) / np.sum(weight)))


def plot_fit(ident: Identifier, result: FitResult, out: Path | str, windows: int = 12) -> Path:
    """Logged against simulated body velocities (before and after the fit) over the first `windows` windows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    before, after = (np.asarray(ident.simulate(p))[:windows] for p in (ident.base, result.params))
    target = np.where(np.asarray(ident.weight) > 0, np.asarray(ident.target), np.nan)[:windows]  # logged rows only
    dt = ident.plant.config.control_dt
    t = dt * (np.arange(windows)[:, None] * ident.steps + np.arange(1, ident.steps + 1)[None])
    fig, axes = plt.subplots(6, 1, figsize=(10, 12), sharex=True)
    labels = ["surge u (m/s)", "sway v (m/s)", "heave w (m/s)", "roll rate p (rad/s)", "pitch rate q (rad/s)", "yaw rate r (rad/s)"]
    for k, ax in enumerate(axes):
        for w in range(windows):
            ax.plot(t[w], target[w, :, k], "k.", ms=2, label="log" if w == 0 else None)
            ax.plot(t[w], before[w, :, k], "C3-", lw=1, label="default parameters" if w == 0 else None)
            ax.plot(t[w], after[w, :, k], "C0-", lw=1.2, label="fitted parameters" if w == 0 else None)
        ax.set_ylabel(labels[k], fontsize=8)
    axes[0].legend(fontsize=8, loc="upper right")
    axes[-1].set_xlabel(f"time (s); each {ident.steps * dt:g} s window starts from the logged state")
    fig.tight_layout()
    out = Path(out)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out
