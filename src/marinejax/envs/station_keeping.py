"""Station keeping (pose keeping): hold a position and heading drawn per episode.

Target: position uniform in a box around (0, 0, −5) m (±`target_range` horizontally and vertically)
and a yaw uniform in (−π, π]. The vehicle starts per `reset` around it.

Observation (all in the body frame FLU unless stated), size 18 + number of actions:
  [0:3]   position error, target − position, m
  [3:6]   world up (0, 0, 1) expressed in the body frame (roll and pitch), unitless
  [6:8]   sin, cos of the heading error (target yaw − yaw)
  [8:11]  linear velocity, m/s
  [11:14] angular velocity, rad/s
  [14:-4] last action
  [-4:-1] leaky integral of the position error, m s (see `base`; absent if integral_time_constant = 0)
  [-1]    leaky integral of the heading error, rad s
Reward position term: 1/(1 + (d/position_scale)^2), the form of MarineGym's 0.5/(1 + (1.2 d)^2),
with a 1 m scale by default; `precision` and `heading_precision` (exp(−|heading error| / 0.1 rad))
are sharp near zero error, where those terms and the heading's (1 + cos)/2 are flat. An episode
succeeds when its mean position error over the last second is under `success_threshold_m` and its
mean heading error under `success_heading_deg`.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.envs.base import EnvConfig, MarineEnv, RewardConfig, distance_terms, heading_precision_term
from marinejax.physics import VehicleState


@dataclasses.dataclass(frozen=True)
class StationKeepingConfig(EnvConfig):
    target_depth: float = -5.0  # m, world z of the box centre
    target_range: float = 1.0  # m, target drawn in ±target_range per axis around (0, 0, target_depth)
    reward: RewardConfig = RewardConfig(heading_precision=1.0, heading_precision_scale=0.1)


@struct.dataclass
class StationTarget:
    position: jnp.ndarray  # (3,) m, world
    yaw: jnp.ndarray  # () rad


class StationKeeping(MarineEnv):
    config_class = StationKeepingConfig
    error_window_description = "last 1 s of each episode"
    success_heading_deg = 5.0

    def error_window(self, time):
        """The last second of the episode: the vehicle has arrived, how well does it hold?"""
        c = self.config
        return self.after(time, c.episode_length * c.control_dt - 1.0)

    def _sample_task(self, rng):
        k1, k2 = jax.random.split(rng)
        c = self.config
        pos = jnp.array([0.0, 0.0, c.target_depth]) + jax.random.uniform(k1, (3,), minval=-c.target_range, maxval=c.target_range)
        return StationTarget(position=pos, yaw=jax.random.uniform(k2, minval=-jnp.pi, maxval=jnp.pi))

    def target_position(self, info) -> jnp.ndarray:
        return info["task"].position

    def _initial_pose(self, rng, task: StationTarget) -> VehicleState:
        return self._random_start(rng, task.position, task.yaw)

    def task_observation_fields(self) -> dict[str, slice]:
        return self._pose_observation_fields()

    def observe(self, vs: VehicleState, info, action):
        task: StationTarget = info["task"]
        return self._pose_observation(vs, task.position, task.yaw, action)

    def reward_terms(self, vs: VehicleState, info, action):
        task: StationTarget = info["task"]
        d = jnp.linalg.norm(task.position - vs.position)
        r = self.config.reward
        return {
            **distance_terms(d, r),
            "heading_precision": heading_precision_term(vs.quaternion, task.yaw, r),
            **self._attitude_terms(vs, task.yaw, action, info["last_action"]),
        }
