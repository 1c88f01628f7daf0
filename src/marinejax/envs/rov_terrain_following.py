"""Terrain following for ROVs: survey along a transect at a commanded altitude over an uneven
seabed drawn per episode, seeing the seabed only through the DVL's bottom-lock beams (altimeter)
and the forward-looking sonar. The torpedo AUV's task of the same name is `terrain_following`.

Scene `terrain`, the seabed drawn as for the torpedo (`terrain_following.draw_profile`: a staircase
of 4 m blocks along world +x following `waves` sines of wavelengths in `wavelength` m, the steepest
slope `max_slope`), its mean placing the commanded altitude at a world z in `depth_range` (m).

Episode: a reference point moves along the transect line (world +x, y = 0) from x = 0 at the
commanded speed (drawn in `speed_range`, m/s over the ground); the commanded altitude (drawn in
`altitude_range`, m) and the heading (the transect's, +x) hold for the episode. The vehicle starts at
rest over x = 0 at the commanded altitude ± `start_altitude_error` m, heading within
±`start_heading_error` rad of the transect's.

The altitude (m) is the vertical distance from the vehicle's origin to the block below it; the
policy sees it only as measured: the altimeter's altitude (along the DVL's axis, from its head)
turned vertical and moved to the origin, the last valid one held while the DVL has no bottom lock.

Observation (body frame FLU): the pose observation (`position_error`: the reference point minus
position along and across the transect, and vertically the commanded minus the measured altitude;
world up; sin, cos of the heading error; velocities; last action), then `reference_velocity` (the
reference point's velocity, m/s, body), the leaky integral of that error, the altimeter's altitude and
the sonar's ranges (scene sensors, appended by the base).
Statistics: `position_error` is the altitude error |set-point − altitude| (m; the evaluated one),
with `heading_error_deg`, `along_track_error` (m: how far the vehicle trails the reference point,
negative ahead of it), `cross_track_error` (m off the transect line; beyond `max_cross_track` the
episode ends, a failure), `collision` (1: the hull touched the seabed, which ends the episode) and
`clearance` (m, the hull's lowest point above the seabed). The evaluation window is the episode after
its first `settle` s; an episode succeeds below 0.2 m, without contact.
Reward: `position` on the distance to the reference point at the commanded altitude over the seabed
below the vehicle, `precision` on the altitude error alone, the attitude terms towards the
transect's heading, and `collision`; where weighted, station keeping's `heading_precision`, sharp
about the transect's heading (weight 0 by default).
"""

from __future__ import annotations

import dataclasses
import math
import types

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.config import check_range
from marinejax.envs.base import EnvConfig, MarineEnv, RewardConfig, distance_terms, heading_precision_term
from marinejax.envs.terrain_following import (BLOCK_HALF_HEIGHT, BLOCKS, altitude_from_dvl, block_centres, check_terrain_config,
                                              check_terrain_scene, draw_terrain_episode, hull_clearance, seabed_z)
from marinejax.frames import quat_from_euler, quat_to_mat
from marinejax.physics import VehicleState
from marinejax.plant.altimeter import AltimeterConfig
from marinejax.plant.sensors import SensorConfig
from marinejax.plant.sonar import SonarConfig
from marinejax.vehicle import collision_capsules


@dataclasses.dataclass(frozen=True)
class RovTerrainFollowingConfig(EnvConfig):
    scene: str = "terrain"
    movable_geoms: tuple[str, ...] = dataclasses.field(default=BLOCKS, metadata={"variable_length": True})
    control_dt: float = 0.1  # s (10 Hz: 60 s episodes)
    substeps: int = 2
    episode_length: int = 600  # 60 s: 12-30 m of transect
    max_distance: float = 5.0  # m of altitude error: the episode terminates beyond
    settle: float = 10.0  # s: the evaluation window starts after this
    speed_range: tuple[float, float] = (0.2, 0.5)  # m/s over the ground: an ROV's survey speeds
    altitude_range: tuple[float, float] = (1.0, 2.0)  # m, the altitude set-point
    depth_range: tuple[float, float] = (-20.0, -5.0)  # m, world z: the altitude set-point's mean over the profile
    start_altitude_error: float = 0.3  # m
    start_heading_error: float = math.radians(10.0)  # rad
    max_slope: float = 0.2  # the profile's steepest slope (rise over run)
    wavelength: tuple[float, float] = (20.0, 60.0)  # m
    waves: int = 3
    max_cross_track: float = 10.0  # m off the transect line (world y = 0): beyond, a failure
    # the DVL's beams (altitude) and a sonar fan of 8 beams over 40°, 30° down: it meets a seabed 1.5 m
    # below about 2.6 m ahead (5-13 s at 0.2-0.5 m/s)
    sensors: SensorConfig = SensorConfig(altimeter=AltimeterConfig(enabled=True),
                                         sonar=SonarConfig(enabled=True, beams=8, horizontal_fov=math.radians(40.0),
                                                           tilt=math.radians(30.0)))
    reward: RewardConfig = RewardConfig(position=2.0, position_scale=1.0, precision=1.0, precision_scale=0.1, collision=10.0)

    def __post_init__(self):
        super().__post_init__()
        check_range("speed_range", self.speed_range, positive=True)
        check_range("depth_range", self.depth_range)
        check_terrain_config(self)


@struct.dataclass
class TransectTask:
    altitude: jnp.ndarray  # () m, the altitude set-point
    speed: jnp.ndarray  # () m/s, the reference point's speed along the transect (world +x)
    yaw: jnp.ndarray  # () rad: the heading set-point, the transect's (0)
    tops: jnp.ndarray  # (blocks,) m, world z of each block's top
    ground: jnp.ndarray  # () m, world z of the seabed below the vehicle after the last step
    held: jnp.ndarray  # () m, the altimeter's last valid altitude (along its axis), as of the last step


class RovTerrainFollowing(MarineEnv):
    config_class = RovTerrainFollowingConfig
    error_window_description = "after the first `settle` s of each episode"
    error_units = types.MappingProxyType({**MarineEnv.error_units, "along_track_error": "m", "cross_track_error": "m",
                                          "collision": "", "clearance": "m"})
    success_threshold_m = 0.2  # m of mean altitude error (issue #24's target); a contact ends the episode, a failure

    def __init__(self, vehicle, config: RovTerrainFollowingConfig):
        super().__init__(vehicle, config)
        check_terrain_scene(self)
        self._hull = collision_capsules(self.vehicle.mj_model, self.plant.sys.body_id, self.vehicle.name)
        self._dvl = jnp.asarray(config.sensors.altimeter.position, jnp.float32)
        self._centres = jnp.asarray(block_centres(len(config.movable_geoms)), jnp.float32)

    def error_window(self, time):
        return self.after(time, self.config.settle)

    def _sample_task(self, rng):
        altitude, speed, tops = draw_terrain_episode(rng, self._centres, self.config)
        zero = jnp.zeros(())
        return TransectTask(altitude=altitude, speed=speed, yaw=zero, tops=tops, ground=seabed_z(tops, zero),
                            held=altitude + self._dvl[2])  # level, at the set-point

    def arrange_scene(self, params, task: TransectTask):
        return params.replace(layout=jnp.stack([self._centres, jnp.zeros_like(task.tops), task.tops - BLOCK_HALF_HEIGHT], axis=-1))

    def _initial_pose(self, rng, task: TransectTask) -> VehicleState:
        c = self.config
        k_z, k_yaw = jax.random.split(rng)
        z = task.ground + task.altitude + jax.random.uniform(k_z, minval=-c.start_altitude_error, maxval=c.start_altitude_error)
        yaw = jax.random.uniform(k_yaw, minval=-c.start_heading_error, maxval=c.start_heading_error)
        return VehicleState(position=jnp.zeros(3).at[2].set(z), quaternion=quat_from_euler(0.0, 0.0, yaw), velocity=jnp.zeros(3),
                            angular_velocity=jnp.zeros(3), actuators=jnp.zeros(self.vehicle.num_actuators))

    def advance_task(self, task: TransectTask, vs: VehicleState, info) -> TransectTask:
        """The seabed below the vehicle now, and the altimeter's last valid altitude (its reading of the
        step before: the sensors read after this)."""
        reading = info["scene_sensors"]["altimeter"].reading
        return task.replace(ground=seabed_z(task.tops, vs.position[0]), held=jnp.where(reading.lock, reading.altitude, task.held))

    def _reference_x(self, info) -> jnp.ndarray:
        return info["task"].speed * info["time"]

    def target_position(self, info) -> jnp.ndarray:
        """The reference point at the commanded altitude over the seabed below it (m, world)."""
        task: TransectTask = info["task"]
        x = self._reference_x(info)
        return jnp.stack([x, 0.0, seabed_z(task.tops, x) + task.altitude])

    def measured_altitude(self, vs: VehicleState, info) -> jnp.ndarray:
        """The altitude (m) as the vehicle measures it (`terrain_following.altitude_from_dvl`), the last
        valid one without bottom lock."""
        reading = info["scene_sensors"]["altimeter"].reading
        return altitude_from_dvl(jnp.where(reading.lock, reading.altitude, info["task"].held), vs, self._dvl)

    def _measured_target(self, vs: VehicleState, info) -> jnp.ndarray:
        """The reference point along the transect, at the height where the measured altitude would be
        the set-point (m, world): what the vehicle steers to."""
        task: TransectTask = info["task"]
        z = vs.position[2] + task.altitude - self.measured_altitude(vs, info)
        return jnp.stack([self._reference_x(info), 0.0, z])

    def integral_error(self, vs: VehicleState, info) -> jnp.ndarray:
        """The measured position error (world, m) and the heading error (rad)."""
        return super().integral_error(vs, info).at[:3].set(self._measured_target(vs, info) - vs.position)

    def task_observation_fields(self) -> dict[str, slice]:
        fields = self._pose_observation_fields()
        end = fields["last_action"].stop
        return {**fields, "reference_velocity": slice(end, end + 3)}

    def observe(self, vs: VehicleState, info, action):
        task: TransectTask = info["task"]
        rot = quat_to_mat(vs.quaternion)
        velocity = rot.T @ jnp.stack([task.speed, 0.0, 0.0])
        return jnp.concatenate([self._pose_observation(vs, self._measured_target(vs, info), task.yaw, action), velocity])

    def errors(self, vs: VehicleState, info):
        task: TransectTask = info["task"]
        gap = hull_clearance(self._hull, vs, task.tops)
        return {**super().errors(vs, info), "position_error": jnp.abs(vs.position[2] - seabed_z(task.tops, vs.position[0]) - task.altitude),
                "along_track_error": self._reference_x(info) - vs.position[0], "cross_track_error": jnp.abs(vs.position[1]),
                "collision": (gap < 0).astype(jnp.float32), "clearance": gap}

    def failed(self, errors):
        """The hull touched the seabed, or the vehicle left the transect by more than `max_cross_track` m."""
        return (errors["collision"] > 0) | (errors["cross_track_error"] > self.config.max_cross_track)

    def reward_terms(self, vs: VehicleState, info, action):
        task: TransectTask = info["task"]
        r = self.config.reward
        target = jnp.stack([self._reference_x(info), 0.0, task.ground + task.altitude])  # true: rewards see the exact state
        altitude_error = jnp.abs(vs.position[2] - task.ground - task.altitude)
        terms = {
            "position": distance_terms(jnp.linalg.norm(target - vs.position), r)["position"],
            "precision": distance_terms(altitude_error, r)["precision"],
            **self._attitude_terms(vs, task.yaw, action, info["last_action"]),
            "collision": -(hull_clearance(self._hull, vs, task.tops) < 0).astype(jnp.float32),
        }
        if r.heading_precision:  # station keeping's sharp heading term, only where weighted (the metrics keep their keys)
            terms["heading_precision"] = heading_precision_term(vs.quaternion, task.yaw, r)
        return terms
