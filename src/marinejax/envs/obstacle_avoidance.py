"""Obstacle avoidance: reach a goal 10-30 m away through a field of piles seen only by the sonar.

Scene `pillars` (`models/scenes/pillars.xml`): vertical piles, capsules of radius 0.3-0.6 m through
the water column. Per episode the goal is drawn at a bearing in (−π, π] and a distance in
`goal_distance` from the start ((0, 0, `start_depth`), any heading, at rest), within ±`goal_depth`
of its depth; `obstacles` piles are placed uniformly in a band `field_width` wide along the line
from start to goal, at least `clearance` m (along the line) from either end, and the others parked
1 km away. The goal's position relative to the vehicle is known (as from acoustic positioning);
the piles are seen only through the forward-looking sonar (on by default; `sensors.sonar`).

A collision: a pile's axis closer than its radius plus a collision capsule's radius to that
capsule's axis (the vehicle's own collision geoms, `class="collision"` in its MJCF), measured
horizontally (the piles are vertical and span every depth the task uses). It ends the episode
(`failed`), so its `window_error` is `max_distance`, and costs the reward term `collision`; coming
within `proximity_range` of a pile costs `proximity` (linear in the gap). Surfacing (shallower
than `surface_depth`: no free surface is modelled, so above it the vehicle would fly) also ends
the episode in failure.

Observation (body frame FLU), size 14 + actions + sonar beams:
  [0:3]   goal − position, m
  [3:6]   world up in the body frame
  [6:8]   sin, cos of the bearing to the goal minus the heading
  [8:11]  linear velocity, m/s;  [11:14] angular velocity, rad/s
  [14:14+n] last action;  then the sonar's range per beam, m (`sonar` field)
Reward: distance terms (`position`, `precision`), `progress` (speed towards the goal, m/s), the
heading towards the goal (the sonar looks ahead), `collision`, `proximity`, effort and smoothness.
Success: the mean distance to the goal over the last second below `goal_radius`, with no collision
and without surfacing.
"""

from __future__ import annotations

import dataclasses
import types

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.config import check_nonnegative, check_range
from marinejax.envs.base import EnvConfig, MarineEnv, RewardConfig, distance_terms
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler, quat_to_mat
from marinejax.physics import VehicleState
from marinejax.plant.sensors import SensorConfig
from marinejax.plant.sonar import SonarConfig
from marinejax.vehicle import collision_capsules

PILES = tuple(f"pillar{i}" for i in range(12))  # the movable geoms of the pillars scene
_PARKED = 1000.0  # m: where unused piles go, far beyond any sensor's range


@dataclasses.dataclass(frozen=True)
class ObstacleAvoidanceConfig(EnvConfig):
    scene: str = "pillars"
    movable_geoms: tuple[str, ...] = dataclasses.field(default=PILES, metadata={"variable_length": True})
    control_dt: float = 0.1  # s (10 Hz: 60 s episodes)
    substeps: int = 2
    episode_length: int = 600
    max_distance: float = 40.0  # m from the goal
    integral_time_constant: float = 0.0
    start_depth: float = -5.0  # m, world z of the start
    goal_distance: tuple[float, float] = (10.0, 30.0)  # m, horizontal
    goal_depth: float = 1.0  # m, goal depth within ± this of the start's
    obstacles: int = 8  # piles placed in the field (at most the scene's movable geoms)
    field_width: float = 8.0  # m, across the start-goal line
    clearance: float = 2.0  # m along the line from the start and from the goal without a pile centre
    goal_radius: float = 1.0  # m: success threshold
    surface_depth: float = 0.5  # m: shallower than this the vehicle has surfaced, a failure (no free surface is modelled)
    proximity_range: float = 0.5  # m: closer to a pile than this costs the reward term `proximity`
    sensors: SensorConfig = SensorConfig(sonar=SonarConfig(enabled=True))
    reward: RewardConfig = RewardConfig(position=1.0, position_scale=10.0, precision=1.0, precision_scale=1.0, progress=1.0,
                                        collision=10.0, proximity=1.0, heading=0.3)

    def __post_init__(self):
        super().__post_init__()
        check_range("goal_distance", self.goal_distance, positive=True)
        check_nonnegative(self, ("goal_depth", "field_width", "clearance", "goal_radius", "surface_depth", "proximity_range"))
        if not 0 <= self.obstacles <= len(self.movable_geoms):
            raise UserError(f"config 'obstacles' must be in [0, {len(self.movable_geoms)}] (the movable geoms), got {self.obstacles}")
        if self.goal_distance[0] <= 2 * self.clearance:
            raise UserError(f"config 'goal_distance' must start beyond 2 x clearance ({2 * self.clearance} m), got {self.goal_distance}")


@struct.dataclass
class GoalTask:
    start: jnp.ndarray  # (3,) m, world
    position: jnp.ndarray  # (3,) m, world: the goal
    yaw: jnp.ndarray  # () rad: bearing of the goal from the start (for the heading statistics)
    piles: jnp.ndarray  # (movable, 3) m, world: pile centres (parked ones 1 km away)
    distance: jnp.ndarray  # () m: distance to the goal after the last step
    progress: jnp.ndarray  # () m: distance gained over the last step


class ObstacleAvoidance(MarineEnv):
    config_class = ObstacleAvoidanceConfig
    error_window_description = "last 1 s of each episode"
    error_units = types.MappingProxyType({**MarineEnv.error_units, "collision": "", "clearance": "m", "surfaced": ""})

    def __init__(self, vehicle, config: ObstacleAvoidanceConfig):
        super().__init__(vehicle, config)
        m = self.vehicle.mj_model
        self._pile_radius = jnp.asarray(m.geom_size[np.asarray(self.plant.sys.layout_ids, int), 0], jnp.float32)
        self._hull = collision_capsules(m, self.plant.sys.body_id, self.vehicle.name)

    @property
    def success_threshold_m(self) -> float:
        return self.config.goal_radius

    def error_window(self, time):
        c = self.config
        return self.after(time, c.episode_length * c.control_dt - 1.0)

    def _sample_task(self, rng):
        c = self.config
        k = jax.random.split(rng, 5)
        start = jnp.array([0.0, 0.0, c.start_depth])
        bearing = jax.random.uniform(k[0], minval=-jnp.pi, maxval=jnp.pi)
        distance = jax.random.uniform(k[1], minval=c.goal_distance[0], maxval=c.goal_distance[1])
        axis = jnp.array([jnp.cos(bearing), jnp.sin(bearing), 0.0])
        side = jnp.array([-axis[1], axis[0], 0.0])
        goal = start + distance * axis + jnp.array([0.0, 0.0, 1.0]) * jax.random.uniform(k[2], minval=-c.goal_depth, maxval=c.goal_depth)
        n = len(c.movable_geoms)
        along = c.clearance + jax.random.uniform(k[3], (n,)) * (distance - 2 * c.clearance)
        across = (jax.random.uniform(k[4], (n,)) - 0.5) * c.field_width
        piles = start + along[:, None] * axis + across[:, None] * side
        parked = jnp.stack([_PARKED + 10.0 * jnp.arange(n), jnp.zeros(n), jnp.full(n, c.start_depth)], axis=-1)
        piles = jnp.where((jnp.arange(n) < c.obstacles)[:, None], piles, parked)
        return GoalTask(start=start, position=goal, yaw=bearing, piles=piles, distance=distance * jnp.ones(()), progress=jnp.zeros(()))

    def arrange_scene(self, params, task: GoalTask):
        return params.replace(layout=task.piles)

    def target_position(self, info) -> jnp.ndarray:
        return info["task"].position

    def _initial_pose(self, rng, task: GoalTask) -> VehicleState:
        yaw = jax.random.uniform(rng, minval=-jnp.pi, maxval=jnp.pi)
        return VehicleState(position=task.start, quaternion=quat_from_euler(0.0, 0.0, yaw), velocity=jnp.zeros(3),
                            angular_velocity=jnp.zeros(3), actuators=jnp.zeros(self.vehicle.num_actuators))

    def advance_task(self, task: GoalTask, vs: VehicleState, info) -> GoalTask:
        distance = jnp.linalg.norm(task.position - vs.position)
        return task.replace(distance=distance, progress=task.distance - distance)

    def _bearing(self, vs: VehicleState, task: GoalTask) -> jnp.ndarray:
        to_goal = task.position - vs.position
        return jnp.arctan2(to_goal[1], to_goal[0])

    def task_observation_fields(self) -> dict[str, slice]:
        return self._pose_observation_fields()

    def observe(self, vs: VehicleState, info, action):
        task: GoalTask = info["task"]
        return self._pose_observation(vs, task.position, self._bearing(vs, task), action)

    def clearance(self, vs: VehicleState, piles: jnp.ndarray) -> jnp.ndarray:
        """Horizontal gap (m) between each pile's surface and the nearest collision capsule's, (piles,)."""
        rot = quat_to_mat(vs.quaternion)
        a = (vs.position + self._hull.a @ rot.T)[:, :2]  # (capsules, 2) segment ends, world xy
        b = (vs.position + self._hull.b @ rot.T)[:, :2]
        p = piles[:, None, :2]  # (piles, 1, 2)
        ab = b - a
        t = jnp.clip(jnp.sum((p - a) * ab, -1) / jnp.maximum(jnp.sum(ab * ab, -1), 1e-9), 0.0, 1.0)
        gap = jnp.linalg.norm(p - (a + t[..., None] * ab), axis=-1) - self._hull.radius - self._pile_radius[:, None]
        return jnp.min(gap, axis=-1)

    def errors(self, vs: VehicleState, info) -> dict[str, jnp.ndarray]:
        gap = jnp.min(self.clearance(vs, info["params"].layout))
        surfaced = vs.position[2] > -self.config.surface_depth
        return {**super().errors(vs, info), "collision": (gap < 0).astype(jnp.float32), "clearance": gap,
                "surfaced": surfaced.astype(jnp.float32)}

    def failed(self, errors):
        return (errors["collision"] > 0) | (errors["surfaced"] > 0)

    def reward_terms(self, vs: VehicleState, info, action):
        task: GoalTask = info["task"]
        r = self.config.reward
        d = task.distance
        gap = jnp.min(self.clearance(vs, info["params"].layout))
        return {
            **distance_terms(d, r),
            "progress": task.progress / self.config.control_dt,
            "collision": -(gap < 0).astype(jnp.float32),
            "proximity": -jnp.clip(1.0 - gap / self.config.proximity_range, 0.0, 1.0),
            **self._attitude_terms(vs, self._bearing(vs, task), action, info["last_action"]),
        }

