"""Classical controllers for every task, behind `control.Controller` (what a trained policy uses).

They read the env's observation through `MarineEnv.observation_fields()`, exactly what a policy
sees (in `observation_mode="sensors"` too), and command the thrusters in [−1, 1].

PID (`pid_controller`), per degree of freedom in the body frame, designed on the vehicle's nominal
model linearised around hover, one decoupled axis at a time: M_i ë + D_i ė = τ_i, with M_i the
rigid-body plus added mass (inertia) and D_i the linear damping. A PID on that axis gives the
closed loop M s³ + (D + k_d) s² + k_p s + k_i; placing its three poles at −ω (critically damped):
  k_p = 3 M ω², k_d = 3 M ω − D (≥ 0), k_i = M ω³,
with one bandwidth ω for translation and one for rotation, twice as fast (`PIDConfig`). The
bandwidth is tuned per env by `tune_pid`: the one of a fixed grid with the lowest mean error over
episodes drawn from a seed other than the evaluation's (the thruster lag and the 20 Hz control
rate, which the design model leaves out, are what stops higher bandwidths from paying off). The integral is the env's
leaky integral of the error (in the observation); roll and pitch have no integral (k_i = 0 leaves
M s² + 3 M ω s + 3 M ω²: poles at √3 ω with damping ratio √3/2): the restoring wrench (weight,
buoyancy, centre of buoyancy) is compensated from the measured attitude instead.
Feedforward: the reference velocity, and the damping it needs (linear and quadratic). The wrench
is allocated to the thrusters with the pseudo-inverse of the allocation matrix (least squares:
the 6-thruster BlueROV2 cannot make a pitch moment) and turned into throttles through the inverse
of the T200 curve at the nominal supply voltage. The thruster lag is not in the design model.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from marinejax.control import Controller
from marinejax.envs.base import MarineEnv
from marinejax.errors import UserError
from marinejax.thrusters import t200_thrust


@dataclasses.dataclass(frozen=True)
class PIDConfig:
    """Closed-loop bandwidths (rad/s): the triple pole of each axis sits at −bandwidth."""

    translation_bandwidth: float = 1.5
    rotation_bandwidth: float = 3.0

    def __post_init__(self):
        for name in ("translation_bandwidth", "rotation_bandwidth"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise UserError(f"PID '{name}' must be finite and > 0 (rad/s), got {value!r}")


@dataclasses.dataclass(frozen=True)
class PIDGains:
    kp: np.ndarray  # (6,) N/m, N m/rad
    kd: np.ndarray  # (6,) N s/m, N m s/rad
    ki: np.ndarray  # (6,) N/(m s), N m/(rad s); zero for roll and pitch


def pid_gains(env: MarineEnv, config: PIDConfig = PIDConfig()) -> PIDGains:
    """Gains by pole placement on the nominal hover model of `env`'s vehicle (module docstring)."""
    p = env.plant.nominal_params()
    mass = np.concatenate([np.full(3, float(p.mass)), np.asarray(p.inertia, float)]) + np.asarray(p.hydro.added_mass, float)
    damping = np.asarray(p.hydro.linear_damping, float)
    w = np.array([config.translation_bandwidth] * 3 + [config.rotation_bandwidth] * 3)
    kp = 3 * mass * w**2
    kd = np.maximum(3 * mass * w - damping, 0.0)
    ki = mass * w**3 * np.array([1, 1, 1, 0, 0, 1.0])
    return PIDGains(kp=kp, kd=kd, ki=ki)


def inverse_thrust(env: MarineEnv, samples: int = 801):
    """throttle(thrust): the inverse of each thruster's steady T200 curve at the nominal voltage and
    gain (thrust in N along the thruster axis → throttle in [−1, 1]; beyond the curve: ±1)."""
    p = env.plant.nominal_params()
    u = np.linspace(-1.0, 1.0, samples)
    f = np.asarray(t200_thrust(env.vehicle.sys.thrusters.curve, jnp.asarray(u), p.voltage))
    keep = np.abs(f) > 1e-6  # drop the dead band, where thrust is zero for a range of throttles
    f_grid = np.concatenate([f[keep & (u < 0)], [0.0], f[keep & (u > 0)]])
    u_grid = np.concatenate([u[keep & (u < 0)], [0.0], u[keep & (u > 0)]])
    if np.any(np.diff(f_grid) <= 0):
        raise UserError("the thruster curve is not monotonic; it cannot be inverted")
    f_grid, u_grid = jnp.asarray(f_grid), jnp.asarray(u_grid)
    gain = jnp.asarray(p.thruster_gain)

    def throttle(thrust: jax.Array) -> jax.Array:
        return jnp.interp(thrust / gain, f_grid, u_grid, left=-1.0, right=1.0)

    return throttle


def pid_controller(env: MarineEnv, config: PIDConfig = PIDConfig()) -> Controller:
    """The PID of the module docstring on `env` (thruster action mode), reading its observation."""
    if env.config.action_mode != "thrusters":
        raise UserError(f"the PID controller commands thrusters; the env has action_mode={env.config.action_mode!r}")
    fields = env.observation_fields()
    gains = pid_gains(env, config)
    kp, kd, ki = (jnp.asarray(g, jnp.float32) for g in (gains.kp, gains.kd, gains.ki))
    p = env.plant.nominal_params()
    g = env.plant.gravity
    net_up = float(p.net_buoyancy(g))  # N, buoyancy minus weight, along world up
    buoyancy = float(p.hydro.fluid_density * p.hydro.volume * g)  # N
    cob = jnp.asarray(p.hydro.center_of_buoyancy, jnp.float32)  # m, body
    lin_d, quad_d = jnp.asarray(p.hydro.linear_damping[:3]), jnp.asarray(p.hydro.quadratic_damping[:3])
    alloc_pinv = jnp.asarray(np.linalg.pinv(np.asarray(env.vehicle.sys.thrusters.allocation)), jnp.float32)
    throttle = inverse_thrust(env)
    has_integral = "integral_position" in fields

    def act(carry, obs, info):
        e = obs[fields["position_error"]]
        v = obs[fields["velocity"]]
        w = obs[fields["angular_velocity"]]
        up = obs[fields["up"]]
        s, c = obs[fields["heading"]]
        v_ref = obs[fields["reference_velocity"]] if "reference_velocity" in fields else jnp.zeros(3)
        roll, pitch = jnp.arctan2(up[1], up[2]), -jnp.arcsin(jnp.clip(up[0], -1.0, 1.0))
        error = jnp.concatenate([e, jnp.stack([-roll, -pitch, jnp.arctan2(s, c)])])
        rate_error = jnp.concatenate([v_ref - v, -w])
        if has_integral:
            # the observation's leaky integral ∫ e exp(−(t−s)/T) ds; close to ∫ e for times below T
            integral = jnp.concatenate([obs[fields["integral_position"]], jnp.zeros(2), obs[fields["integral_heading"]]])
        else:
            integral = jnp.zeros(6)
        tau = kp * error + kd * rate_error + ki * integral
        feedforward = lin_d * v_ref + quad_d * jnp.abs(v_ref) * v_ref
        restoring = jnp.concatenate([net_up * up, jnp.cross(cob, buoyancy * up)])  # what weight and buoyancy do
        wrench = tau + jnp.concatenate([feedforward, jnp.zeros(3)]) - restoring
        return jnp.clip(throttle(alloc_pinv @ wrench), -1.0, 1.0), carry

    return Controller(init=lambda key: (), act=act)


TUNING_BANDWIDTHS = (1.0, 2.0, 3.0, 4.0, 6.0)  # rad/s, translation; rotation twice as fast
TUNING_SEED = 1  # episodes for tuning; `marinejax eval` evaluates on another seed (12345)


def tune_pid(env: MarineEnv, episodes: int = 16, seed: int = TUNING_SEED,
             bandwidths: tuple[float, ...] = TUNING_BANDWIDTHS, progress=None) -> tuple[PIDConfig, dict[float, float]]:
    """The PIDConfig of the grid `bandwidths` with the lowest mean window error (the task's evaluation
    statistic) over `episodes` episodes of `env` from `seed`; returns it and every candidate's error (m)."""
    from marinejax.train.statistics import rollout_controller, summarize

    errors = {}
    for w in bandwidths:
        config = PIDConfig(translation_bandwidth=w, rotation_bandwidth=2 * w)
        stats = summarize(env, rollout_controller(env, pid_controller(env, config), episodes, seed))
        errors[w] = stats["position_error_mean_m"]
        if progress is not None:
            progress(f"PID tuning: bandwidth {w:g} rad/s (rotation {2 * w:g}): mean error {errors[w]:.4f} m")
    best = min(errors, key=errors.get)
    return PIDConfig(translation_bandwidth=best, rotation_bandwidth=2 * best), errors


CONTROLLERS = ("pid",)


def make_controller(name: str, env: MarineEnv, progress=None) -> tuple[Controller, dict]:
    """A classical controller by name (`CONTROLLERS`), tuned for `env`; returns it and a description
    (gains and tuning results) for reports."""
    if name not in CONTROLLERS:
        raise UserError(f"unknown controller {name!r}; valid: {list(CONTROLLERS)}")
    config, errors = tune_pid(env, progress=progress)
    gains = pid_gains(env, config)
    info = {"controller": name, "config": dataclasses.asdict(config),
            "gains": {k: np.round(getattr(gains, k), 3).tolist() for k in ("kp", "kd", "ki")},
            "tuning": {"seed": TUNING_SEED, "mean_error_m_by_bandwidth": {str(k): v for k, v in errors.items()}}}
    return pid_controller(env, config), info
