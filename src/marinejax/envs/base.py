"""The shared machinery of every marinejax task: a Brax `Env` over one vehicle.

A task subclass draws its episode target (`_sample_task`), places the vehicle (`_initial_pose`),
and computes its observation, reward terms and tracking error (`_evaluate`). Everything here is
pure and jit/vmap-able; names and sizes are resolved at construction.

State.info holds all episode randomness, so a full reset re-draws it:
  rng, time (s since episode start), task (the target or trajectory), current (CurrentState),
  dynamics (the physical parameters of this episode), disturbance (a constant external force and
  torque, `envs.disturbance`), last_action, integral (the integrated error, see below).

Integral action: a policy that sees only the present error cannot remove a steady offset (net
weight, a current, a disturbance force) that it was not trained on. Every task therefore appends to
its observation a leaky, clipped integral of the tracking error, as a PI controller's integrator:
  I ← exp(−dt/T) I + dt · clip(e, ±integral_error_clip),  observed as [R^T I_position, I_heading],
with e the world-frame position error (m) and the heading error (rad), T = integral_time_constant.
Clipping the integrand and the leak bound the wind-up during a long approach (|I| ≤ T · clip), so
the integral is useful again within T seconds of arriving. `integral_time_constant = 0` drops the
4 components.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from brax.envs.base import Env, State

from marinejax.envs.config import check_range
from marinejax.envs.current import CurrentConfig, sample_current, step_current
from marinejax.envs.disturbance import DisturbanceConfig, body_wrench, sample_disturbance
from marinejax.envs.randomization import RandomizationConfig, apply_dynamics, nominal_dynamics, sample_dynamics
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler, quat_to_euler, quat_to_mat
from marinejax.physics import (
    COMMAND_MODES,
    VehicleState,
    check_integrator,
    control_step,
    from_physics,
    to_physics,
    with_timestep,
)
from marinejax.vehicle import Vehicle, load_vehicle


@dataclasses.dataclass(frozen=True)
class ResetConfig:
    """Start state relative to the task's target, drawn uniformly per episode."""

    position: float = 2.0  # m, horizontal offset per axis in ±position
    depth: float = 1.0  # m, vertical offset in ±depth
    tilt: float = 0.3  # rad, roll and pitch in ±tilt
    yaw: float = math.pi  # rad, yaw relative to the target heading in ±yaw
    velocity: float = 0.1  # m/s, body velocity per axis in ±velocity
    angular_velocity: float = 0.1  # rad/s, per axis


@dataclasses.dataclass(frozen=True)
class RewardConfig:
    """Weights of the reward terms (each logged as metrics['reward/<term>'], weighted) and scales.

    position: distance term of MarineGym's paper, in (0, 1], scale `position_scale` (m);
    precision: exp(−d / precision_scale), sharp near zero error (weights tuned on station keeping); upright: ((up_z + 1)/2)^2;
    heading: (1 + cos(heading error))/2; effort: −mean(action^2); smoothness: −mean(Δaction^2);
    angular_velocity: −|ω|^2 (rad^2/s^2).
    """

    position: float = 2.0
    position_scale: float = 1.0
    precision: float = 1.0
    precision_scale: float = 0.1
    upright: float = 0.3
    heading: float = 0.3
    effort: float = 0.02
    smoothness: float = 0.02
    angular_velocity: float = 0.02


@dataclasses.dataclass(frozen=True)
class EnvConfig:
    """Settings shared by every task. Times in s, lengths in m."""

    param_set: str | None = None  # vehicle parameter set (None: the vehicle's default)
    control_dt: float = 0.05  # s per action (20 Hz)
    substeps: int = 1  # physics steps per action (50 ms with the second-order midpoint integrator)
    integrator: str = "midpoint"  # "midpoint" (second order) or "euler" (first order, needs <= 0.02 s steps)
    episode_length: int = 200  # actions per episode (truncation, applied by the training wrapper)
    action_mode: str = "thrusters"  # thrusters: throttles in [−1, 1]; wrench: body wrench / wrench_scale
    wrench_scale: tuple[float, float, float, float, float, float] = (80.0, 80.0, 100.0, 15.0, 15.0, 15.0)  # N, N m
    max_distance: float = 5.0  # m from the target: the episode terminates beyond
    integral_time_constant: float = 2.0  # s, leak of the integrated error in the observation; 0: not observed
    integral_error_clip: float = 0.2  # m and rad, per axis: the integrand is clipped to ± this
    reward: RewardConfig = RewardConfig()
    reset: ResetConfig = ResetConfig()
    current: CurrentConfig = CurrentConfig()
    randomization: RandomizationConfig = RandomizationConfig()
    disturbance: DisturbanceConfig = DisturbanceConfig()

    def __post_init__(self):
        if self.action_mode not in COMMAND_MODES:
            raise UserError(f"config 'action_mode' must be one of {list(COMMAND_MODES)}, got {self.action_mode!r}")
        for name in ("control_dt", "max_distance", "integral_error_clip"):
            if not getattr(self, name) > 0:
                raise UserError(f"config '{name}' must be > 0, got {getattr(self, name)}")
        if self.substeps < 1 or self.episode_length < 1:
            raise UserError(f"config 'substeps' and 'episode_length' must be >= 1, got {self.substeps}, {self.episode_length}")
        check_integrator(self.integrator, self.control_dt / self.substeps)
        if not self.integral_time_constant >= 0:
            raise UserError(f"config 'integral_time_constant' must be >= 0 (0: off), got {self.integral_time_constant}")
        if any(s <= 0 for s in self.wrench_scale):
            raise UserError(f"config 'wrench_scale' must be positive, got {self.wrench_scale}")
        for name in ("position", "depth", "tilt", "yaw", "velocity", "angular_velocity"):
            check_range(f"reset.{name}", (0.0, getattr(self.reset, name)), low=0.0)


def heading_error(quat: jnp.ndarray, target_yaw: jnp.ndarray) -> jnp.ndarray:
    """Target yaw minus current yaw (rad), wrapped to (−π, π]."""
    yaw = quat_to_euler(quat)[2]
    return jnp.arctan2(jnp.sin(target_yaw - yaw), jnp.cos(target_yaw - yaw))


class MarineEnv(Env):
    """Base of the registered tasks: a Brax Env (reset(rng) -> State, step(state, action) -> State).

    Besides `position_error` (m, every step), every task logs `window_error`: the position error
    weighted so that its sum over an episode is the mean error over the task's evaluation window
    (`error_window`), the statistic `marinejax eval` reports. An episode that ends early adds
    `max_distance` on its last step, so it can never look like a success. Brax's evaluation sums
    metrics over episodes, so `eval/episode_window_error` during training is the same statistic.
    """

    config_class = EnvConfig
    error_window_description = "every step"  # what `error_window` selects, for reports

    def __init__(self, vehicle: str, config: EnvConfig):
        self.config = config
        self.vehicle: Vehicle = load_vehicle(vehicle, param_set=config.param_set)
        # Brax's domain-randomization wrapper swaps this attribute while tracing; read it only here.
        self.sys = with_timestep(self.vehicle.sys, config.control_dt / config.substeps)
        n = self.vehicle.num_thrusters
        self._action_size = n if config.action_mode == "thrusters" else 6
        self._wrench_scale = jnp.asarray(config.wrench_scale, jnp.float32)
        times = config.control_dt * np.arange(1, config.episode_length + 1)
        self._window_steps = int(np.sum(self.error_window(times)))
        if self._window_steps == 0:
            raise UserError(
                f"episode of {config.episode_length} steps x {config.control_dt} s has no step in the evaluation "
                f"window ({self.error_window_description}); use a longer episode_length"
            )

    @classmethod
    def default_config(cls) -> EnvConfig:
        """This task's default config (an immutable value; override with marinejax.make(name, **overrides))."""
        return cls.config_class()

    # --- Brax Env interface -------------------------------------------------------------
    @property
    def action_size(self) -> int:
        return self._action_size

    @functools.cached_property
    def observation_size(self) -> int:
        return int(jax.eval_shape(self.reset, jax.random.PRNGKey(0)).obs.shape[-1])

    @property
    def backend(self) -> str:
        return "mjx"

    @property
    def dt(self) -> float:
        """Control period, s."""
        return self.config.control_dt

    def reset(self, rng: jax.Array) -> State:
        cfg = self.config
        rng, k_task, k_pose, k_cur, k_dyn, k_dist = jax.random.split(rng, 6)
        task = self._sample_task(k_task)
        current = sample_current(k_cur, cfg.current)
        dynamics = sample_dynamics(k_dyn, self.sys, cfg.randomization) if cfg.randomization.enabled else nominal_dynamics(self.sys)
        sys = apply_dynamics(self.sys, dynamics)
        start = self._initial_pose(k_pose, task)
        ps = to_physics(sys, start)
        info: dict[str, Any] = {
            "rng": rng,
            "time": jnp.zeros(()),
            "task": task,
            "current": current,
            "dynamics": dynamics,
            "last_action": jnp.zeros(self.action_size),
            "integral": jnp.zeros(4),
            "disturbance": sample_disturbance(k_dist, cfg.disturbance),
        }
        vs = from_physics(sys, ps)
        obs, terms, errors = self._evaluate(vs, info, jnp.zeros(self.action_size))
        obs = self._with_integral(obs, vs, info["integral"])
        metrics = self._metrics(terms, errors, jnp.zeros(()), jnp.zeros(()))
        metrics["window_error"] = jnp.zeros(())
        return State(pipeline_state=ps, obs=obs, reward=jnp.zeros(()), done=jnp.zeros(()), metrics=metrics, info=info)

    def step(self, state: State, action: jax.Array) -> State:
        cfg = self.config
        if action.shape != (self.action_size,):
            raise UserError(f"action must have shape ({self.action_size},) for this env ({cfg.action_mode} mode), got {action.shape}")
        info = dict(state.info)
        action = jnp.clip(action, -1.0, 1.0)
        rng, k_cur = jax.random.split(info["rng"])
        current = step_current(info["current"], k_cur, cfg.control_dt, cfg.current)
        sys = apply_dynamics(self.sys, info["dynamics"])
        command = action if cfg.action_mode == "thrusters" else action * self._wrench_scale
        external = None
        if cfg.disturbance.enabled:
            rot = quat_to_mat(from_physics(sys, state.pipeline_state).quaternion)
            external = body_wrench(info["disturbance"], rot)
        ps = control_step(sys, state.pipeline_state, command, current.value, cfg.substeps, cfg.action_mode,
                          cfg.integrator, external)
        finite = jnp.all(jnp.isfinite(ps.data.qpos)) & jnp.all(jnp.isfinite(ps.data.qvel)) & jnp.all(jnp.isfinite(ps.thrust))
        # Never propagate a non-finite state: keep the last finite one and end the episode.
        ps = jax.tree.map(lambda new, old: jnp.where(finite, new, old), ps, state.pipeline_state)
        info.update(rng=rng, time=info["time"] + cfg.control_dt, current=current)
        vs = from_physics(sys, ps)
        info["integral"] = self._integrate_error(info["integral"], vs, info)
        obs, terms, errors = self._evaluate(vs, info, action)
        obs = self._with_integral(obs, vs, info["integral"])
        info["last_action"] = action
        out = errors["position_error"] > cfg.max_distance
        nonfinite = 1.0 - finite.astype(jnp.float32)
        done = jnp.maximum(out.astype(jnp.float32), nonfinite)
        new = self._metrics(terms, errors, nonfinite, out.astype(jnp.float32))
        in_window = self.error_window(info["time"]).astype(jnp.float32) / self._window_steps
        new["window_error"] = jnp.where(done > 0, cfg.max_distance, errors["position_error"] * in_window)
        reward = sum(v for k, v in new.items() if k.startswith("reward/")) * finite
        # Update in place: wrappers (Brax's EvalWrapper) may have added keys that must survive.
        metrics = dict(state.metrics)
        metrics.update({k: jnp.where(finite, v, 0.0) if k.startswith("reward/") else v for k, v in new.items()})
        return state.replace(pipeline_state=ps, obs=jnp.where(finite, obs, 0.0), reward=reward, done=done, metrics=metrics, info=info)

    # --- helpers ------------------------------------------------------------------------
    def _integrate_error(self, integral: jnp.ndarray, vs: VehicleState, info: dict) -> jnp.ndarray:
        """Leaky, clipped integral (4,) of [world position error (m), heading error (rad)] (module docstring)."""
        c = self.config
        if c.integral_time_constant == 0:
            return integral
        error = jnp.concatenate([
            self.target_position(info) - vs.position,
            heading_error(vs.quaternion, info["task"].yaw)[None],
        ])
        leak = math.exp(-c.control_dt / c.integral_time_constant)
        return leak * integral + c.control_dt * jnp.clip(error, -c.integral_error_clip, c.integral_error_clip)

    def _with_integral(self, obs: jnp.ndarray, vs: VehicleState, integral: jnp.ndarray) -> jnp.ndarray:
        """obs with the integral appended: position part in the body frame (m s), heading part (rad s)."""
        if self.config.integral_time_constant == 0:
            return obs
        return jnp.concatenate([obs, quat_to_mat(vs.quaternion).T @ integral[:3], integral[3:]])

    def _metrics(self, terms, errors, nonfinite, out) -> dict[str, jnp.ndarray]:
        weights = self.config.reward
        metrics = {f"reward/{k}": getattr(weights, k) * v for k, v in terms.items()}
        metrics.update(errors)
        metrics["nonfinite"] = nonfinite
        metrics["out_of_bounds"] = out
        return metrics

    def _common_terms(self, vs: VehicleState, target_yaw, action, last_action) -> tuple[dict, dict, jnp.ndarray]:
        """Attitude, effort and smoothness terms; heading error; body-frame attitude observation."""
        rot = quat_to_mat(vs.quaternion)
        up_body = rot[2, :]  # world up in the body frame: roll and pitch
        dpsi = heading_error(vs.quaternion, target_yaw)
        terms = {
            "upright": ((up_body[2] + 1.0) / 2.0) ** 2,
            "heading": (1.0 + jnp.cos(dpsi)) / 2.0,
            "effort": -jnp.mean(action**2),
            "smoothness": -jnp.mean((action - last_action) ** 2),
            "angular_velocity": -jnp.sum(vs.angular_velocity**2),
        }
        errors = {"heading_error_deg": jnp.degrees(jnp.abs(dpsi))}
        attitude_obs = jnp.concatenate([up_body, jnp.stack([jnp.sin(dpsi), jnp.cos(dpsi)]), vs.velocity, vs.angular_velocity])
        return terms, errors, attitude_obs

    def _random_start(self, rng: jax.Array, position: jnp.ndarray, yaw: jnp.ndarray) -> VehicleState:
        """A start state around `position` (m, world) and heading `yaw` (rad), per config.reset."""
        r = self.config.reset
        k = jax.random.split(rng, 5)
        offset = jax.random.uniform(k[0], (3,), minval=-1.0, maxval=1.0) * jnp.array([r.position, r.position, r.depth])
        roll, pitch = jax.random.uniform(k[1], (2,), minval=-r.tilt, maxval=r.tilt)
        dyaw = jax.random.uniform(k[2], minval=-r.yaw, maxval=r.yaw)
        return VehicleState(
            position=position + offset,
            quaternion=quat_from_euler(roll, pitch, yaw + dyaw),
            velocity=jax.random.uniform(k[3], (3,), minval=-r.velocity, maxval=r.velocity),
            angular_velocity=jax.random.uniform(k[4], (3,), minval=-r.angular_velocity, maxval=r.angular_velocity),
            thrust=jnp.zeros(self.vehicle.num_thrusters),
        )

    # --- task hooks ---------------------------------------------------------------------
    def error_window(self, time):
        """True where time (s since episode start, end of a step; NumPy or JAX array) is in the
        window the evaluation statistics average over. Tasks override it with their own."""
        return time >= 0.0

    def target_position(self, info: dict) -> jnp.ndarray:
        """Where the vehicle should be now (m, world): the station or the reference point at info['time']."""
        raise NotImplementedError

    def _sample_task(self, rng: jax.Array) -> Any:
        raise NotImplementedError

    def _initial_pose(self, rng: jax.Array, task: Any) -> VehicleState:
        raise NotImplementedError

    def _evaluate(self, vs: VehicleState, info: dict, action: jnp.ndarray):
        """(observation, unweighted reward terms, error metrics) at the state `vs` (time info['time'])."""
        raise NotImplementedError

