"""ROV docking: fly into the docking station of the `rov_dock` scene and settle on its landing point.

The station is the scene's, fixed: its landing point at the origin, its opening towards −x, a
funnel of guide bars around the opening (`models/scenes/rov_dock.xml`). Drawing the station's
position and heading per episode is the same as drawing the start around a fixed station, which is
what is done (the physics has no preferred place or direction; the current's direction is drawn).
Start: `start_distance` m from the landing point horizontally, at a bearing within
±`start_bearing` rad of the station's axis in front of its opening, within ±`start_depth` m of its
depth, at any heading, at rest. Target: the landing point with heading 0 (facing +x, into the
station).

Docked (the metric `docked`, 1 or 0): the CG inside the station (at most `dock_inside` m before the
landing point along its axis), within `dock_tolerance` m of it sideways and vertically, heading
within `dock_heading` degrees, speed below `dock_speed` m/s, all held for `dock_hold` s. Contacts
with the station are allowed; a contact force above `impact_threshold` N is an impact, penalized by
the reward term `impact` (−(|F| − threshold)/threshold) and logged as `impact_force` (N).

Observation: station keeping's (`station_keeping`), towards the landing point, with the integral.
The evaluation window is the last second of the episode, as for station keeping.
"""

from __future__ import annotations

import dataclasses
import math
import types

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.config import check_nonnegative, check_range
from marinejax.envs.base import EnvConfig, RewardConfig, heading_error
from marinejax.envs.station_keeping import StationKeeping
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler
from marinejax.physics import VehicleState


@dataclasses.dataclass(frozen=True)
class DockingConfig(EnvConfig):
    scene: str = "rov_dock"
    episode_length: int = 600  # 30 s at 20 Hz
    max_distance: float = 10.0  # m from the landing point: the episode terminates beyond
    start_distance: tuple[float, float] = (3.0, 6.0)  # m, horizontal, from the landing point
    start_bearing: float = 1.0  # rad, either side of the station's axis, in front of the opening
    start_depth: float = 1.0  # m, vertical offset in ±
    dock_inside: float = 0.1  # m: the CG at most this far before the landing point along the axis
    dock_tolerance: float = 0.05  # m, sideways and vertically
    dock_heading: float = 5.0  # degrees
    dock_speed: float = 0.1  # m/s
    dock_hold: float = 1.0  # s
    impact_threshold: float = 30.0  # N
    reward: RewardConfig = RewardConfig(impact=1.0)

    def __post_init__(self):
        super().__post_init__()
        check_range("start_distance", self.start_distance, low=0.0)
        check_nonnegative(self, ("start_bearing", "start_depth", "dock_inside", "dock_tolerance", "dock_heading", "dock_speed",
                                 "dock_hold", "impact_threshold"))
        if self.start_bearing > math.pi / 2:
            raise UserError(f"config 'start_bearing' must be at most pi/2 (in front of the opening), got {self.start_bearing}")


@struct.dataclass
class DockTask:
    position: jnp.ndarray  # (3,) m, world: the landing point
    yaw: jnp.ndarray  # () rad: the station's heading
    hold: jnp.ndarray  # () s: how long the docked conditions have held


class Docking(StationKeeping):
    config_class = DockingConfig
    success_heading_deg = None  # `docked`, the task's own success, requires the heading within dock_heading
    error_units = types.MappingProxyType({**StationKeeping.error_units, "lateral_error": "m", "impact_force": "N", "docked": ""})
    success_threshold_m = 0.05

    def __init__(self, vehicle, config: DockingConfig):
        super().__init__(vehicle, config)
        if not self.plant.sys.contacts:
            raise UserError(f"the Docking task needs a scene with contacts (the station); scene {config.scene!r} has none")

    def _sample_task(self, rng):
        return DockTask(position=jnp.zeros(3), yaw=jnp.zeros(()), hold=jnp.zeros(()))

    def _initial_pose(self, rng, task: DockTask) -> VehicleState:
        c = self.config
        k = jax.random.split(rng, 4)
        distance = jax.random.uniform(k[0], minval=c.start_distance[0], maxval=c.start_distance[1])
        bearing = jax.random.uniform(k[1], minval=-c.start_bearing, maxval=c.start_bearing)
        depth = jax.random.uniform(k[2], minval=-c.start_depth, maxval=c.start_depth)
        offset = jnp.array([-distance * jnp.cos(bearing), distance * jnp.sin(bearing), depth])
        yaw = jax.random.uniform(k[3], minval=-jnp.pi, maxval=jnp.pi)
        return VehicleState(position=task.position + offset, quaternion=quat_from_euler(0.0, 0.0, yaw),
                            velocity=jnp.zeros(3), angular_velocity=jnp.zeros(3), actuators=jnp.zeros(self.vehicle.num_actuators))

    def _docked_now(self, vs: VehicleState, task: DockTask) -> jnp.ndarray:
        c = self.config
        offset = vs.position - task.position  # the station's axis is world x (its heading is 0)
        return ((offset[0] >= -c.dock_inside) & (jnp.linalg.norm(offset[1:]) <= c.dock_tolerance)
                & (jnp.degrees(jnp.abs(heading_error(vs.quaternion, task.yaw))) <= c.dock_heading)
                & (jnp.linalg.norm(vs.velocity) <= c.dock_speed))

    def advance_task(self, task: DockTask, vs: VehicleState, info) -> DockTask:
        return task.replace(hold=jnp.where(self._docked_now(vs, task), task.hold + self.config.control_dt, 0.0))

    def errors(self, vs: VehicleState, info) -> dict[str, jnp.ndarray]:
        task: DockTask = info["task"]
        return {
            **super().errors(vs, info),
            "lateral_error": jnp.linalg.norm((vs.position - task.position)[1:]),
            "impact_force": contact_force(info),
            # float32 time steps: half a step of margin
            "docked": (task.hold >= self.config.dock_hold - 0.5 * self.config.control_dt).astype(jnp.float32),
        }

    def reward_terms(self, vs: VehicleState, info, action):
        force = contact_force(info)
        threshold = self.config.impact_threshold
        return {**super().reward_terms(vs, info, action), "impact": -jnp.maximum(force - threshold, 0.0) / threshold}


def contact_force(info) -> jnp.ndarray:
    """The magnitude (N) of the force the scene exerts on the vehicle (`info["contact"]`)."""
    return jnp.linalg.norm(info["contact"][:3])
