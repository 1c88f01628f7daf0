"""The shared machinery of every marinejax task: a Brax `Env` over one `Plant` (vehicle + physics).

A task subclass draws its episode target (`_sample_task`), places the vehicle (`_initial_pose`),
says where the vehicle should be (`target_position`) and when its error counts (`error_window`),
and defines its observation (`observe`) and reward terms (`reward_terms`). The position and heading
errors are the base's (`errors`), from `target_position` and the task's yaw. Everything here is
pure and jit/vmap-able; names and sizes are resolved at construction.

One step (`_transition`), in order: the action is clipped to [−1, 1] and, in sensor mode, delayed
(`_delay_action`); the plant advances its actuators and physics; the task updates its own state
(`advance_task`) and sets the scene's mechanisms for the next step (`operate_scene`: a dock's
latch); the enabled scene sensors (altimeter, sonar) cast their rays into the scene; in
sensor mode the navigation sensors measure and the estimator updates (`_sense`); the task
observes (`observe`, plus the integral, the scene sensors' readings and the privileged parts:
`_observation`), delayed in sensor mode (`_delay_observation`); the task's reward terms and errors
are computed; `_termination` ends the episode beyond `max_distance`, on a non-finite state or when
the task says it `failed` (a collision), and makes the metrics.

State.pipeline_state is the `PlantState` (MJX data, thruster lag, ocean current). State.info holds
all episode randomness, so a full reset re-draws it:
  rng, time (s since episode start), task (the target or trajectory), params (`PlantParams`: the
  physical parameters and disturbance of this episode), last_action, integral (see below), and in a
  scene with contacts (`config.scene`) contact: what the scene exerts on the vehicle after the step
  (`Plant.contact_wrench`: force N, world; moment N m about the CG, body), for the task's hooks;
  with scene sensors enabled, scene_sensors: each one's last reading, by name.
`reset(rng, params)` starts an episode with parameters of your own instead of drawn ones (a task
that places obstacles still places them: `arrange_scene`).

Observation: an array (the task's observation, then the integral below, then the enabled scene
sensors' readings: fields "altimeter" and "sonar"). With `privileged_observation=True` it is a
dict: "state" is that array (what the policy sees) and "privileged_state" appends what no sensor
gives (current, disturbance, the episode's parameters, `Plant.privileged`) for an asymmetric critic
(Brax PPO: `value_obs_key="privileged_state"`).

Observation modes (`observation_mode`): "state" observes the exact state. "sensors" observes what
the vehicle's sensors give (`plant/sensors.py`: IMU, depth, attitude, DVL, position fix) through the
complementary filter it would run (`plant/estimator.py`): the task's `observe` reads the estimated
state, so the layout, units and frames are the same as in "state" mode. The policy then sees the
observation of `sensors.latency.observation` steps ago and its action reaches the thrusters
`sensors.latency.action` steps later (both drawn per episode with `sensors.randomization`). Rewards,
errors, termination and the statistics always use the exact state; the privileged state (critic)
starts with the exact-state observation.

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
import types
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from brax.envs.base import Env, State

from marinejax.config import check_range
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler, quat_to_euler, quat_to_mat
from marinejax.physics import VehicleState
from marinejax.plant import Plant, PlantConfig, PlantParams, PlantState
from marinejax.plant.current import CurrentState
from marinejax.plant.estimator import estimated_state, estimator_init, estimator_update
from marinejax.vehicle import Vehicle


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
    angular_velocity: −|ω|^2 (rad^2/s^2); speed (tasks with a speed set-point): exp(−|speed error| /
    speed_scale); speed_penalty (the same tasks): −|speed error| (m/s), a slope at any error;
    heading_precision (tasks that use it): exp(−|heading error| / heading_precision_scale), sharp where
    the heading term is flat; impact (tasks in a scene with contacts): −(|contact force| − threshold)/threshold
    above the task's threshold; progress (tasks with a goal): the speed towards it, m/s (the distance
    gained over the step / dt; the autopilot's: the rate its depth error shrinks, m/s); collision (the
    same): −1 on the step the vehicle hits an obstacle; proximity (the same): −(1 − gap / range) within
    the task's range of an obstacle, 0 beyond;
    docked (docking): the torpedo's 1 on the step the latch closes, the ROV's the time docked without a
    break over the time it must hold, at most 1; dive (the autopilot): −(the sine of the flight-path
    angle towards the depth set-point short of a reference's), where positive (`envs/autopilot.py`).
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
    speed: float = 0.0
    speed_scale: float = 0.2  # m/s
    speed_penalty: float = 0.0
    heading_precision: float = 0.0
    heading_precision_scale: float = 0.05  # rad
    impact: float = 0.0
    progress: float = 0.0
    collision: float = 0.0
    proximity: float = 0.0
    docked: float = 0.0
    dive: float = 0.0


OBSERVATION_MODES = ("state", "sensors")

# What each observation field (`MarineEnv.observation_fields`) holds: (unit, frame, meaning).
# Body frame: FLU (x forward, y left, z up) at the CG; world frame: z up.
OBSERVATION_FIELDS = {
    "position_error": ("m", "body", "target (or the path's closest point) minus position"),
    "reference_ahead": ("m", "body", "reference positions at t, t + spacing, ... minus position, 3 per point"),
    "reference_velocity": ("m/s", "body", "velocity of the reference at t"),
    "path_ahead": ("m", "body", "points of the path preview_spacing, 2 preview_spacing, ... m beyond the closest one, minus position"),
    "tangent": ("1", "body", "unit tangent of the path at the closest point"),
    "depth_error": ("m", "world z", "depth set-point minus depth (positive: rise), clipped to ±depth_clip"),
    "speed_error": ("m/s", "-", "speed set-point minus the surge speed (autopilot) or the speed along the path"),
    "set_point_depth": ("m / 10", "world z", "depth set-point divided by 10"),
    "set_point_heading": ("1", "world", "sin, cos of the heading set-point"),
    "set_point_speed": ("m/s", "-", "speed set-point"),
    "up": ("1", "body", "world up (0, 0, 1): roll and pitch"),
    "heading": ("1", "-", "sin, cos of the heading error (target minus heading)"),
    "velocity": ("m/s", "body", "linear velocity"),
    "angular_velocity": ("rad/s", "body", "angular velocity"),
    "actuators": ("1", "-", "actuator states, each scaled to [-1, 1] by its command range"),
    "last_action": ("1", "-", "the previous action, in [-1, 1]"),
    "altitude_error_ahead": ("m", "world z", "altitude set-point minus the height over the seabed the sonar's echoes show "
                                             "ahead (terrain following), clipped to ±depth_clip"),
    "distance_ahead": ("m", "world", "how far ahead those echoes lie, horizontally along the heading"),
    "dock": ("m", "body", "the dock's latch point (its tube's entrance on the axis) minus the torpedo's nose; "
                          "the ROV station's landing point minus the CG"),
    "integral_position": ("m s", "body", "leaky integral of the position error"),
    "integral_heading": ("rad s", "-", "leaky integral of the heading error"),
}  # and each enabled scene sensor's field (`plant.scene_sensors`)


@dataclasses.dataclass(frozen=True)
class EnvConfig(PlantConfig):
    """Settings shared by every task: the plant's (`PlantConfig`: timing, integrator, action mode,
    current, randomization, disturbance) and the episode's. Times in s, lengths in m."""

    episode_length: int = 200  # actions per episode (truncation, applied by the training wrapper)
    max_distance: float = 5.0  # m from the target: the episode terminates beyond
    integral_time_constant: float = 2.0  # s, leak of the integrated error in the observation; 0: not observed
    integral_error_clip: float = 0.2  # m and rad, per axis: the integrand is clipped to ± this
    privileged_observation: bool = False  # obs {"state", "privileged_state"} for an asymmetric critic
    observation_mode: str = "state"  # "state": exact; "sensors": the estimate from the sensor models
    reward: RewardConfig = RewardConfig()
    reset: ResetConfig = ResetConfig()

    def __post_init__(self):
        super().__post_init__()
        for name in ("max_distance", "integral_error_clip"):
            if not getattr(self, name) > 0:
                raise UserError(f"config '{name}' must be > 0, got {getattr(self, name)}")
        if self.observation_mode not in OBSERVATION_MODES:
            raise UserError(f"config 'observation_mode' must be one of {list(OBSERVATION_MODES)}, got {self.observation_mode!r}")
        if self.episode_length < 1:
            raise UserError(f"config 'episode_length' must be >= 1, got {self.episode_length}")
        if not self.integral_time_constant >= 0:
            raise UserError(f"config 'integral_time_constant' must be >= 0 (0: off), got {self.integral_time_constant}")
        for name in ("position", "depth", "tilt", "yaw", "velocity", "angular_velocity"):
            check_range(f"reset.{name}", (0.0, getattr(self.reset, name)), low=0.0)


def distance_terms(d: jnp.ndarray, reward: RewardConfig) -> dict[str, jnp.ndarray]:
    """The reward terms of a distance d ≥ 0 (m) from where the task wants the vehicle: position
    1/(1 + (d/position_scale)^2) and precision exp(−d/precision_scale), unweighted."""
    return {"position": 1.0 / (1.0 + (d / reward.position_scale) ** 2), "precision": jnp.exp(-d / reward.precision_scale)}


def heading_error(quat: jnp.ndarray, target_yaw: jnp.ndarray) -> jnp.ndarray:
    """Target yaw minus current yaw (rad), wrapped to (−π, π]."""
    yaw = quat_to_euler(quat)[2]
    return jnp.arctan2(jnp.sin(target_yaw - yaw), jnp.cos(target_yaw - yaw))


def heading_precision_term(quat: jnp.ndarray, target_yaw: jnp.ndarray, reward: RewardConfig) -> jnp.ndarray:
    """The sharp heading reward term exp(−|heading error| / heading_precision_scale), unweighted, of
    the attitude `quat` towards heading `target_yaw` (rad)."""
    return jnp.exp(-jnp.abs(heading_error(quat, target_yaw)) / reward.heading_precision_scale)


class MarineEnv(Env):
    """Base of the registered tasks: a Brax Env (reset(rng) -> State, step(state, action) -> State).

    Besides `position_error` (m, every step), every task logs `window_error`: the position error
    weighted so that its sum over an episode is the mean error over the task's evaluation window
    (`error_window`), the statistic `marinejax eval` reports. An episode that ends early adds
    `max_distance` on its last step, so it can never look like a success. Brax's evaluation sums
    metrics over episodes, so `eval/episode_window_error` during training is the same statistic.
    """

    config_class = EnvConfig
    vehicle_kinds = ("rov",)  # the kinds of vehicle (`marinejax.vehicle.VEHICLE_KINDS`) this task is for
    error_window_description = "every step"  # what `error_window` selects, for reports
    # the unit of each of the task's errors (`errors`), for reports; a task with other errors adds them
    error_units = types.MappingProxyType({"position_error": "m", "heading_error_deg": "°", "speed_error": "m/s"})
    success_threshold_m = 0.1  # m: an episode succeeds when its mean error over the window is below this
    # °: where set, an episode succeeds only if its mean heading error over the window is also below this
    success_heading_deg: float | None = None
    # where set, the name of an error (1 or 0) whose value at an episode's last step is its success,
    # instead of the thresholds above (a task with its own criterion, e.g. `docked`)
    success_flag: str | None = None
    # The task's accuracy targets, error name (`errors`) → the largest mean over the window it may
    # have (in the error's unit; position_error: the window error, m). For each other error named
    # here the metrics also have `window_<name>`, weighted as `window_error` is, so that training
    # evaluations report its mean over the window and a checkpoint can be chosen on every target
    # (`best_on="targets"` in the algorithm's settings). Empty: the window error alone.
    targets: types.MappingProxyType = types.MappingProxyType({})

    def __init__(self, vehicle: str | Vehicle, config: EnvConfig):
        self.config = config
        self.plant = Plant(vehicle, config)
        self.vehicle: Vehicle = self.plant.vehicle
        times = config.control_dt * np.arange(1, config.episode_length + 1)
        self._window_steps = int(np.sum(self.error_window(times)))
        if self._window_steps == 0:
            raise UserError(
                f"episode of {config.episode_length} steps x {config.control_dt} s has no step in the evaluation "
                f"window ({self.error_window_description}); use a longer episode_length"
            )
        # Traced once per env and reused by every caller's jit (Brax's training and evaluation
        # loops, the auto-reset inside every step, tests): inlined into each caller, the MJX step
        # and the task logic are retraced by each, about a second apiece for the step.
        self._jit_transition = jax.jit(self._transition)
        self._jit_reset = jax.jit(self._reset)

    @classmethod
    def default_config(cls) -> EnvConfig:
        """This task's default config (an immutable value; override with marinejax.make(name, **overrides))."""
        return cls.config_class()

    # --- Brax Env interface -------------------------------------------------------------
    @property
    def action_size(self) -> int:
        return self.plant.action_size

    @functools.cached_property
    def _state_shape(self) -> State:
        return jax.eval_shape(lambda: self.reset(jax.random.PRNGKey(0)))

    @property
    def observation_size(self) -> int | dict[str, tuple[int, ...]]:
        """Size of the observation; with privileged_observation, the shape of each key (as Brax)."""
        obs = self._state_shape.obs
        return jax.tree.map(lambda x: x.shape, obs) if isinstance(obs, dict) else int(obs.shape[-1])

    @property
    def backend(self) -> str:
        return "mjx"

    @property
    def dt(self) -> float:
        """Control period, s."""
        return self.config.control_dt

    def reset(self, rng: jax.Array, params: PlantParams | None = None) -> State:
        """A new episode: target, start pose, current and (unless `params` is given) the physical
        parameters drawn from `rng`."""
        return self._jit_reset(rng, params)

    def _reset(self, rng: jax.Array, params: PlantParams | None) -> State:
        rng, k_task, k_pose, k_cur, k_params, k_sensors = jax.random.split(rng, 6)
        task = self._sample_task(k_task)
        if params is None:
            params = self.plant.sample_params(k_params)
        params = self.arrange_scene(params, task)  # the episode's obstacles, for a task that places them
        start = self._initial_pose(k_pose, task)
        ps = self.plant.init(k_cur, params, start)
        task = self.fit_task(k_task, task, params, ps.current, self.plant.vehicle_state(ps))  # what the episode's current and physics allow
        fitted = self.fit_start(task, ps.current, start)
        if fitted is not start:  # a task that moves its start: the plant there, with the same current (the same key)
            ps = self.plant.init(k_cur, params, fitted)
        vs = self.plant.vehicle_state(ps)
        action = jnp.zeros(self.action_size)
        info: dict[str, Any] = {
            "rng": rng,
            "time": jnp.zeros(()),
            "task": task,
            "params": params,
            "last_action": action,
            "integral": jnp.zeros(4),
        }
        if self.plant.sys.contacts:
            info["contact"] = jnp.zeros(6)
        if self.plant.scene_sensors:  # altimeter, sonar: they see the scene
            info["scene_sensors"] = self.plant.scene_sensors.init(jax.random.fold_in(k_sensors, 1), self.plant.cast(params, ps))
        if self._sensor_mode:
            suite = self.plant.sensors
            k_draw, k_init = jax.random.split(k_sensors)
            info["sensors"], m = suite.init(k_init, suite.sample_params(k_draw), vs)
            info["estimator"] = estimator_init(suite, m)
            info["action_buffer"] = jnp.zeros((suite.max_action_latency + 1, self.action_size))
        obs = self._observation(vs, info, action, ps)
        if self._sensor_mode:
            policy_obs = self._policy_part(obs)
            size = self.plant.sensors.max_observation_latency + 1
            info["observation_buffer"] = jnp.broadcast_to(policy_obs, (size,) + policy_obs.shape)
        metrics = self._metrics(self.reward_terms(vs, info, action), self.errors(vs, info), jnp.zeros(()), jnp.zeros(()))
        metrics["window_error"] = jnp.zeros(())
        metrics.update({f"window_{name}": jnp.zeros(()) for name in self._window_targets})
        return State(pipeline_state=ps, obs=obs, reward=jnp.zeros(()), done=jnp.zeros(()), metrics=metrics, info=info)

    def step(self, state: State, action: jax.Array) -> State:
        # only the env's own info keys go through the jitted transition: wrappers add others
        info = {k: state.info[k] for k in self._state_shape.info}
        ps, obs, reward, done, new, info = self._jit_transition(state.pipeline_state, info, action)
        # Update in place: wrappers (Brax's EvalWrapper) may have added keys that must survive.
        metrics = {**state.metrics, **new}
        return state.replace(pipeline_state=ps, obs=obs, reward=reward, done=done, metrics=metrics, info={**state.info, **info})

    def _transition(self, pipeline_state: PlantState, info: dict, action: jax.Array):
        """One control step, in the order it happens: (plant state, observation, reward, done, metrics, info)."""
        info = dict(info)
        k_scene = jax.random.fold_in(info["rng"], 1)
        rng, k_plant = jax.random.split(info["rng"])
        if self._sensor_mode:
            rng, k_sensors = jax.random.split(rng)
        action = jnp.clip(action, -1.0, 1.0)
        applied, info = self._delay_action(info, action)  # actuation latency (sensor mode)
        ps, finite = self.plant.step(info["params"], pipeline_state, applied, k_plant)  # actuators and physics
        info.update(rng=rng, time=info["time"] + self.config.control_dt)
        if self.plant.sys.contacts:
            info["contact"] = self.plant.contact_wrench(ps)
        vs = self.plant.vehicle_state(ps)
        info["task"] = self.advance_task(info["task"], vs, info)  # the task's own state (a path's closest point)
        ps = self.operate_scene(ps, info["task"])  # the scene's mechanisms (a dock's latch), from the next step on
        if self.plant.scene_sensors:  # altimeter, sonar: ray casts into the scene
            info["scene_sensors"] = self.plant.scene_sensors.step(info["scene_sensors"], self.plant.cast(info["params"], ps), k_scene)
        if self._sensor_mode:
            info = self._sense(info, vs, k_sensors)  # sensors, then the vehicle's estimator
        obs, info = self._delay_observation(info, self._observation(vs, info, action, ps, integrate=True))
        terms, errors = self.reward_terms(vs, info, action), self.errors(vs, info)
        info["last_action"] = action
        done, metrics = self._termination(terms, errors, finite, info["time"])
        reward = sum(v for k, v in metrics.items() if k.startswith("reward/")) * finite
        # a step that went non-finite reports zeros, never NaN: it ends the episode (metrics["nonfinite"])
        metrics = {k: jnp.where(finite, v, 0.0) if k.startswith("reward/") else v for k, v in metrics.items()}
        obs = jax.tree.map(lambda o: jnp.where(finite, o, 0.0), obs)
        return ps, obs, reward, done, metrics, info

    # --- the parts of a step --------------------------------------------------------------
    def _delay_action(self, info: dict, action: jnp.ndarray) -> tuple[jnp.ndarray, dict]:
        """The action that reaches the actuators now: in sensor mode the one of
        `sensors.latency.action` steps ago (a buffer in info), else `action`."""
        if not self._sensor_mode:
            return action, info
        buffer = jnp.concatenate([action[None], info["action_buffer"][:-1]])
        return buffer[info["sensors"].params.action_latency], {**info, "action_buffer": buffer}

    def _sense(self, info: dict, vs: VehicleState, rng: jax.Array) -> dict:
        """Sensor mode: the sensors measure the exact state `vs`; the estimator takes the measurement."""
        suite = self.plant.sensors
        altimeter = info.get("scene_sensors", {}).get("altimeter")
        sensors, m = suite.step(info["sensors"], vs, rng, bottom_lock=None if altimeter is None else altimeter.reading.lock)
        return {**info, "sensors": sensors, "estimator": estimator_update(suite, info["estimator"], m)}

    def _delay_observation(self, info: dict, obs):
        """The observation the policy sees now: in sensor mode the one of `sensors.latency.observation`
        steps ago (the critic's privileged part stays current), else `obs`."""
        if not self._sensor_mode:
            return obs, info
        buffer = jnp.concatenate([self._policy_part(obs)[None], info["observation_buffer"][:-1]])
        delayed = buffer[info["sensors"].params.observation_latency]
        return ({**obs, "state": delayed} if isinstance(obs, dict) else delayed), {**info, "observation_buffer": buffer}

    def _termination(self, terms: dict, errors: dict, finite: jnp.ndarray, time: jnp.ndarray) -> tuple[jnp.ndarray, dict]:
        """done (beyond `max_distance` or non-finite) and the step's metrics: weighted reward terms,
        errors, flags and the window error (what an episode's evaluation statistic sums)."""
        cfg = self.config
        out = errors["position_error"] > cfg.max_distance
        nonfinite = 1.0 - finite.astype(jnp.float32)
        done = jnp.maximum(jnp.maximum(out.astype(jnp.float32), nonfinite), self.failed(errors).astype(jnp.float32))
        metrics = self._metrics(terms, errors, nonfinite, out.astype(jnp.float32))
        in_window = self.error_window(time).astype(jnp.float32) / self._window_steps
        metrics["window_error"] = jnp.where(done > 0, cfg.max_distance, errors["position_error"] * in_window)
        metrics.update({f"window_{name}": errors[name] * in_window for name in self._window_targets})
        return done, metrics

    @property
    def _window_targets(self) -> tuple[str, ...]:
        """The errors of `targets` other than the position error (the window error's)."""
        return tuple(name for name in self.targets if name != "position_error")

    # --- errors, observation and reward pieces shared by the tasks -------------------------
    def errors(self, vs: VehicleState, info: dict) -> dict[str, jnp.ndarray]:
        """position_error (m, to `target_position`) and heading_error_deg (to the task's yaw)."""
        return {
            "heading_error_deg": jnp.degrees(jnp.abs(heading_error(vs.quaternion, info["task"].yaw))),
            "position_error": jnp.linalg.norm(self.target_position(info) - vs.position),
        }

    @functools.cached_property
    def error_names(self) -> tuple[str, ...]:
        """The names of the task's errors (`errors`), as logged in the metrics: position_error,
        heading_error_deg and any of the task's own."""
        shape = self._state_shape
        return tuple(jax.eval_shape(lambda ps, info: self.errors(self.plant.vehicle_state(ps), info), shape.pipeline_state, shape.info))

    @functools.cached_property
    def _sensor_mode(self) -> bool:
        return self.config.observation_mode == "sensors"

    def measured_state(self, vs: VehicleState, info: dict) -> VehicleState:
        """What the policy's observation is computed from: the exact state `vs`, or in sensor mode
        the estimate from the sensors (`plant/estimator.py`)."""
        if not self._sensor_mode:
            return vs
        return estimated_state(info["estimator"], info["sensors"].last, vs.actuators)

    def _observation(self, vs: VehicleState, info: dict, action: jnp.ndarray, ps: PlantState, integrate: bool = False):
        """The observation at exact state `vs` (updates info["integral"] first when `integrate`)."""
        measured = self.measured_state(vs, info)
        if integrate:
            info["integral"] = self._integrate_error(info["integral"], measured, info)

        def with_integral(state: VehicleState) -> jnp.ndarray:
            obs = self.observe(state, info, action)
            if self.config.integral_time_constant > 0:
                integral = info["integral"]
                obs = jnp.concatenate([obs, quat_to_mat(state.quaternion).T @ integral[:3], integral[3:]])
            if self.plant.scene_sensors:
                obs = jnp.concatenate([obs, self.plant.scene_sensors.observe(info["scene_sensors"])])
            return obs

        obs = with_integral(measured)
        if not self.config.privileged_observation:
            return obs
        exact = obs if measured is vs else with_integral(vs)
        return {"state": obs, "privileged_state": jnp.concatenate([exact, self.plant.privileged(info["params"], ps)])}

    def observation_fields(self) -> dict[str, slice]:
        """Where each quantity sits in the observation array (the task's fields, then the integral):
        e.g. "position_error" (body, m), "velocity" (body, m/s), "integral_position" (body, m s).
        Classical controllers read the observation through these, as a policy would."""
        fields = dict(self.task_observation_fields())
        n = self._task_observation_size
        if self.config.integral_time_constant > 0:
            fields.update(integral_position=slice(n, n + 3), integral_heading=slice(n + 3, n + 4))
            n += 4
        for name, size in self.plant.scene_sensors.observation_sizes().items():
            fields[name] = slice(n, n + size)
            n += size
        return fields

    def observation_layout(self) -> list[dict[str, Any]]:
        """The observation array as data: per field its name, [start, stop), unit, frame and meaning
        (`OBSERVATION_FIELDS` and the scene sensors'), in order (fields may overlap: tracking's first
        reference point is its position error)."""
        fields = sorted(self.observation_fields().items(), key=lambda f: (f[1].start, f[1].stop))
        described = {**OBSERVATION_FIELDS, **self.plant.scene_sensors.observation_fields()}
        return [{"name": name, "start": sl.start, "stop": sl.stop, "unit": described[name][0],
                 "frame": described[name][1], "meaning": described[name][2]} for name, sl in fields]

    @functools.cached_property
    def _task_observation_size(self) -> int:
        return max(s.stop for s in self.task_observation_fields().values())

    def task_observation_fields(self) -> dict[str, slice]:
        """The task's observation layout (before the integral): name → slice. Every task provides
        position_error (body, m, to the reference now), up (world up in the body frame), heading
        (sin, cos of the heading error), velocity (body, m/s), angular_velocity (body, rad/s) and
        last_action; tracking tasks also reference_velocity (body, m/s)."""
        raise NotImplementedError

    @staticmethod
    def _policy_part(obs):
        return obs["state"] if isinstance(obs, dict) else obs

    def _integrate_error(self, integral: jnp.ndarray, vs: VehicleState, info: dict) -> jnp.ndarray:
        """Leaky, clipped integral (4,) of [world position error (m), heading error (rad)] (module docstring)."""
        c = self.config
        if c.integral_time_constant == 0:
            return integral
        error = self.integral_error(vs, info)
        leak = math.exp(-c.control_dt / c.integral_time_constant)
        return leak * integral + c.control_dt * jnp.clip(error, -c.integral_error_clip, c.integral_error_clip)

    def integral_error(self, vs: VehicleState, info: dict) -> jnp.ndarray:
        """The error (4,) that the observed integral accumulates: the world-frame position error (m)
        and the heading error (rad), to `target_position` and the task's `yaw`."""
        return jnp.concatenate([self.target_position(info) - vs.position, heading_error(vs.quaternion, info["task"].yaw)[None]])

    def _metrics(self, terms, errors, nonfinite, out) -> dict[str, jnp.ndarray]:
        weights = self.config.reward
        metrics = {f"reward/{k}": getattr(weights, k) * v for k, v in terms.items()}
        metrics.update(errors)
        metrics["nonfinite"] = nonfinite
        metrics["out_of_bounds"] = out
        return metrics

    def _pose_observation_fields(self) -> dict[str, slice]:
        """The layout of `_pose_observation` (tasks that hold or reach a point)."""
        n = self.action_size
        return {"position_error": slice(0, 3), "up": slice(3, 6), "heading": slice(6, 8), "velocity": slice(8, 11),
                "angular_velocity": slice(11, 14), "last_action": slice(14, 14 + n)}

    def _pose_observation(self, vs: VehicleState, position: jnp.ndarray, yaw, action: jnp.ndarray) -> jnp.ndarray:
        """Towards a point `position` (m, world) at heading `yaw` (rad): the position error in the
        body frame, `_attitude_observation` and the last action."""
        rot = quat_to_mat(vs.quaternion)
        return jnp.concatenate([rot.T @ (position - vs.position), self._attitude_observation(vs, yaw), action])

    def _attitude_observation(self, vs: VehicleState, target_yaw) -> jnp.ndarray:
        """World up in the body frame (3), sin and cos of the heading error (2), body linear (m/s) and
        angular (rad/s) velocity (3 + 3)."""
        up_body = quat_to_mat(vs.quaternion)[2, :]
        dpsi = heading_error(vs.quaternion, target_yaw)
        return jnp.concatenate([up_body, jnp.stack([jnp.sin(dpsi), jnp.cos(dpsi)]), vs.velocity, vs.angular_velocity])

    def _attitude_terms(self, vs: VehicleState, target_yaw, action, last_action) -> dict[str, jnp.ndarray]:
        """Unweighted upright, heading, effort, smoothness and angular-velocity reward terms."""
        up_body = quat_to_mat(vs.quaternion)[2, :]  # world up in the body frame: roll and pitch
        dpsi = heading_error(vs.quaternion, target_yaw)
        return {
            "upright": ((up_body[2] + 1.0) / 2.0) ** 2,
            "heading": (1.0 + jnp.cos(dpsi)) / 2.0,
            "effort": -jnp.mean(action**2),
            "smoothness": -jnp.mean((action - last_action) ** 2),
            "angular_velocity": -jnp.sum(vs.angular_velocity**2),
        }

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
            actuators=jnp.zeros(self.vehicle.num_actuators),
        )

    # --- task hooks ---------------------------------------------------------------------
    def error_window(self, time):
        """True where time (s since episode start, end of a step; NumPy or JAX array) is in the
        window the evaluation statistics average over. Tasks override it with their own."""
        return time >= 0.0

    def after(self, time, t0: float):
        """For `error_window`s: time > t0 (s), with half a control step of margin, since the env
        accumulates time in float32."""
        return time > t0 + 0.5 * self.config.control_dt

    def target_position(self, info: dict) -> jnp.ndarray:
        """Where the vehicle should be now (m, world): the station or the reference point at info['time']."""
        raise NotImplementedError

    def _sample_task(self, rng: jax.Array) -> Any:
        """The episode's task (a pytree with at least `yaw`, the heading to hold, rad)."""
        raise NotImplementedError

    def _initial_pose(self, rng: jax.Array, task: Any) -> VehicleState:
        raise NotImplementedError

    def fit_task(self, rng: jax.Array, task: Any, params: PlantParams, current: CurrentState, start: VehicleState) -> Any:
        """The episode's task (drawn by `_sample_task` from the same `rng`) fitted to what the
        episode's physics and current allow, without moving its start (`start`: the vehicle as
        `_initial_pose` placed it). Most tasks keep it as drawn."""
        return task

    def fit_start(self, task: Any, current: CurrentState, start: VehicleState) -> VehicleState:
        """The start (`start`: as `_initial_pose` placed it) fitted to the episode's current at the
        start (`current`) and fitted task. Most tasks keep it, returning `start` itself (the plant is
        then not initialised again)."""
        return start

    def arrange_scene(self, params: PlantParams, task: Any) -> PlantParams:
        """The episode's parameters with the scene's movable geoms placed for `task`
        (`params.layout`, `PlantConfig.movable_geoms`). Most tasks leave the scene as it is."""
        return params

    def failed(self, errors: dict[str, jnp.ndarray]) -> jnp.ndarray:
        """Whether the episode ends now in failure (beside leaving `max_distance` or going
        non-finite): a collision, for a task that forbids one. Default: never."""
        return jnp.zeros((), bool)

    def advance_task(self, task: Any, vs: VehicleState, info: dict) -> Any:
        """The task after a step that ended in exact state `vs` (before the errors, observation and
        reward are computed), with the step's `info` (time, and in a scene with contacts `contact`):
        for a task with a state of its own, such as the closest point on a path or a latch. Most
        tasks' targets are fixed per episode: unchanged."""
        return task

    def operate_scene(self, ps: PlantState, task: Any) -> PlantState:
        """The plant state with the scene's mechanisms set for the task's state after this step,
        acting from the next physics step on: a dock's latch closed once the vehicle is docked
        (`Plant.latch`). Most tasks leave the scene as it is."""
        return ps

    def observe(self, vs: VehicleState, info: dict, action: jnp.ndarray) -> jnp.ndarray:
        """The task's observation (before the integral) at state `vs`, time info['time'], after `action`."""
        raise NotImplementedError

    def reward_terms(self, vs: VehicleState, info: dict, action: jnp.ndarray) -> dict[str, jnp.ndarray]:
        """Unweighted reward terms, named as the fields of `RewardConfig` that weigh them."""
        raise NotImplementedError
