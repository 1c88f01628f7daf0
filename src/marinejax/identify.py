"""System identification: fit a vehicle's fluid and thruster parameters to a logged run.

Log format (CSV, one row per control step at a constant period; `read_log`, `write_log`):
  time_s                                  s since the start
  u1 .. uN                                throttle per thruster in [−1, 1], the vehicle's thruster order,
                                          applied from this row's time to the next row's
  qw, qx, qy, qz                          attitude, body → world (world z up, body FLU)
  vx_mps, vy_mps, vz_mps                  body-frame velocity over ground (a DVL gives it), m/s
  wx_radps, wy_radps, wz_radps            body-frame angular velocity (the gyro), rad/s
  x_m, y_m, z_m                           optional world position (z up), m
A vehicle in ArduSub logs this from its thruster outputs, the AHRS attitude, the DVL and the gyro.

`excitation(vehicle)` makes a command sequence that moves each degree of freedom in turn and then
all of them (piecewise-constant random levels in wrench space, held 0.5–2 s, within `amplitude` of
the smallest full thrust), allocated to the thrusters; `marinejax excite` writes it as a log with
only time and commands, for a user to run on their vehicle.

`identify(log, vehicle)` fits added mass (6), linear and quadratic damping (6 + 6), displaced
volume, centre of buoyancy (3), one thruster gain for all thrusters and the thruster time constant
by multiple shooting (the thruster gain only on request, see below): the log is cut into windows of `window` seconds; each starts from the logged
state and is simulated with the logged commands by the same differentiable plant the envs use; the
residuals are the simulated minus logged body velocities, angular velocities, roll and pitch, each
divided by its measurement noise. Short windows keep the rollouts from diverging, so long logs and
weakly stable directions do not blow up the fit. The optimiser is Levenberg–Marquardt on the
Jacobian that JAX gives through the rollout (a least-squares problem with 24 unknowns: faster and
more precise here than first-order methods such as optax's Adam), with every parameter kept within
physical bounds. Uncertainty: the Gauss–Newton covariance σ² (JᵀJ)⁻¹ at the optimum, σ² the mean
squared normalised residual; a parameter whose standard deviation exceeds 10 % of its scale is
reported as not determined by the log (relative to the larger of its value and its scale).

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
from marinejax.frames import quat_to_euler
from marinejax.physics import VehicleState
from marinejax.plant import Plant, PlantConfig, PlantParams
from marinejax.thrusters import full_thrust, inverse_t200, lag_step, t200_thrust


@dataclasses.dataclass(frozen=True)
class Log:
    """One logged run (see the module docstring for units and frames); arrays with T rows."""

    time: np.ndarray  # (T,) s
    commands: np.ndarray  # (T, N) throttles
    quaternion: np.ndarray | None = None  # (T, 4)
    velocity: np.ndarray | None = None  # (T, 3) m/s, body
    angular_velocity: np.ndarray | None = None  # (T, 3) rad/s, body
    position: np.ndarray | None = None  # (T, 3) m, world

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
    params = plant.nominal_params()
    curve = plant.vehicle.sys.thrusters.curve
    full = full_thrust(curve, params.voltage)
    alloc = np.asarray(plant.vehicle.sys.thrusters.allocation)
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
              "thruster_gain": jnp.mean(params.thruster_gain), "time_constant": params.time_constant}
    return np.concatenate([np.atleast_1d(np.asarray(values[name], float)) for name, *_ in _FIT])


def _unflatten(base: PlantParams, x: jnp.ndarray) -> PlantParams:
    out, i = {}, 0
    for name, size, _, _ in _FIT:
        out[name] = x[i : i + size] if size > 1 else x[i]
        i += size
    hydro = base.hydro.replace(added_mass=out["added_mass"], linear_damping=out["linear_damping"],
                               quadratic_damping=out["quadratic_damping"], volume=out["volume"],
                               center_of_buoyancy=out["center_of_buoyancy"])
    return base.replace(hydro=hydro, thruster_gain=jnp.full_like(base.thruster_gain, out["thruster_gain"]),
                        time_constant=out["time_constant"])


_SCALE = np.concatenate([s for _, _, s, _ in _FIT])
_LOWER = np.concatenate([np.full(n, lo) for _, n, _, lo in _FIT])


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


class Identifier:
    """Multiple-shooting residuals of a log for one vehicle; jitted once per (log length, window)."""

    def __init__(self, plant: Plant, log: Log, window: float = 1.0, fit_thruster_gain: bool = False):
        if log.quaternion is None or log.velocity is None or log.angular_velocity is None:
            raise UserError("identification needs the attitude (qw..qz), body velocity (vx_mps..) and angular velocity (wx_radps..) columns")
        if log.commands.shape[1] != plant.vehicle.num_thrusters:
            raise UserError(f"the log has {log.commands.shape[1]} thruster columns; vehicle {plant.vehicle.name!r} has {plant.vehicle.num_thrusters}")
        if abs(log.dt - plant.config.control_dt) > 1e-3 * plant.config.control_dt:
            raise UserError(f"the log's period {log.dt:.4f} s differs from the control period {plant.config.control_dt} s; "
                            "resample the log or pass --env control_dt=...")
        self.plant = plant
        self.steps = max(2, int(round(window / plant.config.control_dt)))
        n = (len(log.time) - 1) // self.steps
        if n < 4:
            raise UserError(f"the log is too short: {len(log.time)} rows give {n} windows of {window} s (need at least 4)")
        starts = np.arange(n) * self.steps
        idx = starts[:, None] + np.arange(1, self.steps + 1)[None]
        q = log.quaternion / np.linalg.norm(log.quaternion, axis=1, keepdims=True)
        euler = np.asarray(jax.vmap(quat_to_euler)(jnp.asarray(q)))
        self.start = VehicleState(position=jnp.zeros((n, 3)), quaternion=jnp.asarray(q[starts]),
                                  velocity=jnp.asarray(log.velocity[starts]), angular_velocity=jnp.asarray(log.angular_velocity[starts]),
                                  thrust=jnp.zeros((n, plant.vehicle.num_thrusters)))
        self.all_commands = jnp.asarray(log.commands)
        self.start_rows = jnp.asarray(starts)
        self.commands = jnp.asarray(log.commands[idx - 1])  # the command of row k acts from row k to k + 1
        self.target = jnp.asarray(np.concatenate([log.velocity[idx], log.angular_velocity[idx], euler[idx][..., :2]], axis=-1))
        self.noise = jnp.asarray(_NOISE)
        self.base = plant.nominal_params()
        self.x0 = _flatten(self.base)
        self.free = np.array([fit_thruster_gain or n != "thruster_gain" for n in PARAMETER_NAMES])
        self.residuals = jax.jit(self._residuals)
        self.jacobian = jax.jit(jax.jacfwd(self._residuals))

    def simulate(self, params: PlantParams) -> jnp.ndarray:
        """(windows, steps, 8): body velocity, angular velocity, roll, pitch simulated from each window's start."""
        plant, key = self.plant, jax.random.PRNGKey(0)
        # the thrusters' lag state at each window start: the lag filter run over the whole command
        # history from rest (it does not depend on the rigid-body motion)
        curve, dt = plant.vehicle.sys.thrusters.curve, plant.config.control_dt / plant.config.substeps

        def lag(thrust, u):
            target = t200_thrust(curve, u, params.voltage) * params.thruster_gain
            for _ in range(plant.config.substeps):
                thrust = lag_step(thrust, target, dt, params.time_constant)
            return thrust, thrust

        _, history = jax.lax.scan(lag, jnp.zeros(self.all_commands.shape[1]), self.all_commands)
        history = jnp.concatenate([jnp.zeros((1, history.shape[1])), history])  # thrust at row k

        def window(start, thrust, commands):
            state = plant.init(key, params, start.replace(thrust=thrust))

            def body(state, u):
                state, _ = plant.step(params, state, u, key)
                vs = plant.vehicle_state(state)
                return state, jnp.concatenate([vs.velocity, vs.angular_velocity, quat_to_euler(vs.quaternion)[:2]])

            return jax.lax.scan(body, state, commands)[1]

        return jax.vmap(window)(self.start, history[self.start_rows], self.commands)

    def _residuals(self, z: jnp.ndarray) -> jnp.ndarray:
        x = jnp.asarray(self.x0) + z * jnp.asarray(_SCALE, jnp.float32)
        return ((self.simulate(_unflatten(self.base, x)) - self.target) / self.noise).reshape(-1)

    def fit(self, iterations: int = 30, progress: Callable[[str], None] | None = None) -> FitResult:
        t0 = _time.perf_counter()
        lower = (_LOWER - self.x0) / _SCALE  # bounds on z
        free = self.free
        z = np.zeros(len(self.x0))
        r = np.asarray(self.residuals(jnp.asarray(z, jnp.float32)), float)
        cost0 = cost = float(np.mean(r**2))
        lam = 1e-2
        for it in range(iterations):
            j = np.asarray(self.jacobian(jnp.asarray(z, jnp.float32)), float)[:, free]
            jtj, g = j.T @ j, j.T @ r
            while True:
                step = np.zeros_like(z)
                step[free] = -np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-9), g)
                z_new = np.maximum(z + step, lower)
                r_new = np.asarray(self.residuals(jnp.asarray(z_new, jnp.float32)), float)
                cost_new = float(np.mean(r_new**2)) if np.all(np.isfinite(r_new)) else np.inf
                if cost_new < cost:
                    z, r, lam = z_new, r_new, max(lam / 3, 1e-7)
                    break
                lam *= 4
                if lam > 1e8:
                    break
            improvement = cost - cost_new if cost_new < np.inf else 0.0
            cost = min(cost, cost_new)
            if progress is not None:
                progress(f"iteration {it + 1:2d}: cost {cost:.4g} (mean squared residual / noise²)")
            if lam > 1e8 or improvement < 1e-6 * cost:
                break
        j = np.asarray(self.jacobian(jnp.asarray(z, jnp.float32)), float)[:, free]
        std_z = np.zeros(len(z))
        std_z[free] = np.sqrt(np.maximum(np.diag(np.linalg.pinv(j.T @ j) * cost), 0))
        values = self.x0 + z * _SCALE
        std = std_z * _SCALE
        return FitResult(params=_unflatten(self.base, jnp.asarray(values, jnp.float32)), names=PARAMETER_NAMES,
                         initial=self.x0, values=values, std=std, determined=std < 0.1 * np.maximum(np.abs(values), _SCALE),
                         fitted=free.copy(), cost_before=cost0, cost_after=cost, seconds=_time.perf_counter() - t0)


def simulate_log(plant: Plant, params: PlantParams, commands: np.ndarray, seed: int = 0, noise: bool = True,
                 start: VehicleState | None = None) -> Log:
    """A synthetic log: `commands` run on `params` from rest at 5 m depth (or `start`), measured with
    white noise of the sensor models' size (DVL 1 % + 1 mm/s, gyro, attitude; see `_NOISE`)."""
    key = jax.random.PRNGKey(seed)
    if start is None:
        from marinejax.physics import initial_state

        start = initial_state(plant.vehicle, position=(0.0, 0.0, -5.0))

    @jax.jit
    def run(commands):
        state = plant.init(key, params, start)

        def body(state, u):
            state, finite = plant.step(params, state, u, key)
            vs = plant.vehicle_state(state)
            return state, (vs.position, vs.quaternion, vs.velocity, vs.angular_velocity, finite)

        return jax.lax.scan(body, state, commands)[1]

    pos, quat, vel, ang, finite = (np.asarray(a, float) for a in run(jnp.asarray(commands)))
    if not np.all(finite):
        raise FloatingPointError("the simulated log went non-finite")
    s0 = jax.tree.map(lambda a: np.asarray(a, float)[None], start)
    pos, quat, vel, ang = (np.concatenate([a0, a]) for a0, a in
                           ((s0.position, pos), (s0.quaternion, quat), (s0.velocity, vel), (s0.angular_velocity, ang)))
    commands = np.concatenate([commands, commands[-1:]])
    if noise:
        rng = np.random.default_rng(seed)
        vel = vel + rng.normal(size=vel.shape) * (0.0101 * np.linalg.norm(vel, axis=1, keepdims=True) + 0.001)
        ang = ang + rng.normal(size=ang.shape) * 0.002
        euler = np.asarray(jax.vmap(quat_to_euler)(jnp.asarray(quat))) + rng.normal(size=(len(quat), 3)) * 0.0035
        from marinejax.frames import quat_from_euler

        quat = np.asarray(jax.vmap(quat_from_euler)(euler[:, 0], euler[:, 1], euler[:, 2]))
        pos = pos + rng.normal(size=pos.shape) * 0.05
    time = plant.config.control_dt * np.arange(len(commands))
    return Log(time=time, commands=commands, quaternion=quat, velocity=vel, angular_velocity=ang, position=pos)


def save_param_set(path: Path | str, vehicle: str, result: FitResult, source: str) -> Path:
    """Write the fitted parameters as a parameter-set file for `load_vehicle(name, param_set=path)`
    and every env (`--env param_set=PATH`)."""
    p = result.params
    data = {
        "vehicle": vehicle, "source": source,
        "added_mass": np.asarray(p.hydro.added_mass).tolist(), "linear_damping": np.asarray(p.hydro.linear_damping).tolist(),
        "quadratic_damping": np.asarray(p.hydro.quadratic_damping).tolist(), "volume": float(p.hydro.volume),
        "fluid_density": float(p.hydro.fluid_density), "center_of_buoyancy": np.asarray(p.hydro.center_of_buoyancy).tolist(),
        "mass": float(p.mass), "inertia": np.asarray(p.inertia).tolist(),
        "thruster_gain": float(np.mean(np.asarray(p.thruster_gain))), "thruster_time_constant": float(p.time_constant),
        "fit": {n: {"value": float(v), "std": float(s), "determined": bool(d)}
                for n, v, s, d in zip(result.names, result.values, result.std, result.determined)},
    }
    path = Path(path)
    path.write_text(json.dumps(data, indent=2))
    return path


def prediction_error(plant: Plant, params: PlantParams, log: Log, window: float = 1.0) -> float:
    """RMS (m/s) of the body velocity predicted over `window`-second windows of `log` from each
    window's logged start, with `params`, against the logged velocity."""
    ident = Identifier(plant, log, window)
    sim = np.asarray(ident.simulate(params))
    return float(np.sqrt(np.mean((sim[..., :3] - np.asarray(ident.target)[..., :3]) ** 2)))


def plot_fit(ident: Identifier, result: FitResult, out: Path | str, windows: int = 12) -> Path:
    """Logged against simulated body velocities (before and after the fit) over the first `windows` windows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    before, after = (np.asarray(ident.simulate(p))[:windows] for p in (ident.base, result.params))
    target = np.asarray(ident.target)[:windows]
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
