"""Path tracking: follow a circle, helix or lemniscate drawn per episode (see `trajectories`).

The reference moves along the path at the episode's speed after a smooth ramp; the vehicle starts
near the path's start point, and holds a heading drawn per episode (the BlueROV2 is holonomic).

Observation (body frame FLU unless stated), size 3·m + 18 + number of actions, m = num_reference_points:
  [0:3m]       reference position at t, t + s, …, t + (m−1)s minus position, m (s = reference_spacing)
  [3m:3m+3]    reference velocity at t, m/s
  [3m+3:3m+6]  world up in the body frame
  [3m+6:3m+8]  sin, cos of the heading error
  [3m+8:3m+14] linear (m/s) and angular (rad/s) velocity
  [3m+14:-4]   last action
  [-4:-1]      leaky integral of the position error to the reference at t, m s (see `base`)
  [-1]         leaky integral of the heading error, rad s
Reward position term: exp(−d/position_scale) (MarineGym's 0.5 exp(−1.6 d), rescaled to 1).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.envs.base import EnvConfig, MarineEnv, ResetConfig, RewardConfig
from marinejax.envs.trajectories import TrajectoryConfig, TrajectoryParams, reference, sample_params
from marinejax.errors import UserError
from marinejax.frames import quat_to_mat
from marinejax.physics import VehicleState


@dataclasses.dataclass(frozen=True)
class TrackingConfig(EnvConfig):
    episode_length: int = 400  # 20 s at 20 Hz
    max_distance: float = 1.0  # m from the moving reference
    reset: ResetConfig = ResetConfig(position=0.1, depth=0.1, tilt=0.1, yaw=0.3, velocity=0.05, angular_velocity=0.05)
    reward: RewardConfig = RewardConfig(position_scale=0.625)  # MarineGym's 0.5 exp(−1.6 d)
    trajectory: TrajectoryConfig = TrajectoryConfig()
    num_reference_points: int = 4
    reference_spacing: float = 0.25  # s between the observed reference points

    def __post_init__(self):
        super().__post_init__()
        if self.num_reference_points < 1 or self.reference_spacing <= 0:
            raise UserError(
                f"config 'num_reference_points' must be >= 1 and 'reference_spacing' > 0, got "
                f"{self.num_reference_points}, {self.reference_spacing}"
            )


@struct.dataclass
class TrackingTask:
    trajectory: TrajectoryParams
    yaw: jnp.ndarray  # () rad, heading to hold


class Tracking(MarineEnv):
    config_class = TrackingConfig
    error_window_description = "after the first 2 s"

    def error_window(self, time):
        """After the first 2 s, once the reference has ramped up to speed."""
        return self.after(time, 2.0)

    def __init__(self, vehicle: str, kind: str, config: TrackingConfig):
        self.kind = kind
        super().__init__(vehicle, config)

    def _sample_task(self, rng):
        k1, k2 = jax.random.split(rng)
        return TrackingTask(
            trajectory=sample_params(self.kind, k1, self.config.trajectory),
            yaw=jax.random.uniform(k2, minval=-jnp.pi, maxval=jnp.pi),
        )

    def target_position(self, info) -> jnp.ndarray:
        return reference(self.kind, info["task"].trajectory, info["time"])[0]

    def _initial_pose(self, rng, task: TrackingTask) -> VehicleState:
        start, _ = reference(self.kind, task.trajectory, jnp.zeros(()))
        return self._random_start(rng, start, task.yaw)

    def task_observation_fields(self) -> dict[str, slice]:
        k, n = 3 * self.config.num_reference_points, self.action_size
        return {"position_error": slice(0, 3), "reference_ahead": slice(0, k), "reference_velocity": slice(k, k + 3),
                "up": slice(k + 3, k + 6), "heading": slice(k + 6, k + 8), "velocity": slice(k + 8, k + 11),
                "angular_velocity": slice(k + 11, k + 14), "last_action": slice(k + 14, k + 14 + n)}

    def observe(self, vs: VehicleState, info, action):
        task: TrackingTask = info["task"]
        c = self.config
        times = info["time"] + c.reference_spacing * jnp.arange(c.num_reference_points)
        ref_pos, ref_vel = reference(self.kind, task.trajectory, times)
        rot = quat_to_mat(vs.quaternion)
        ahead = ((ref_pos - vs.position) @ rot).reshape(-1)  # (m, 3) body-frame offsets to the reference points
        return jnp.concatenate([ahead, rot.T @ ref_vel[0], self._attitude_observation(vs, task.yaw), action])

    def reward_terms(self, vs: VehicleState, info, action):
        task: TrackingTask = info["task"]
        d = jnp.linalg.norm(self.target_position(info) - vs.position)
        r = self.config.reward
        return {
            "position": jnp.exp(-d / r.position_scale),
            "precision": jnp.exp(-d / r.precision_scale),
            **self._attitude_terms(vs, task.yaw, action, info["last_action"]),
        }
