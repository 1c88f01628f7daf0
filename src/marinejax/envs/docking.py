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
the reward term `impact` (−(|F| − threshold)/threshold) and logged as `impact_force` (N). The reward
term `docked` is how long the docked conditions have held, over `dock_hold` and capped at 1: paid
on every step from arrival on (an ROV should stay docked, and arriving early is no fault), but only
while the conditions hold without a break, so that a vehicle rocking in place whose speed exceeds
`dock_speed` a few steps a cycle earns little of it.

Guidance: the pose the observation and the reward steer to is a guide point on the station's axis,
not the landing point itself, so that the vehicle lines up in front of the opening before it enters
(flying straight at the landing point jams on the funnel or the cage's side) and arrives slowly. The
guide is the task's state, x_g along the axis (m, negative in front of the landing point): it starts
at the start's projection on the axis (at most `approach_distance` in front) and each step advances
at min(`approach_speed`, `guide_gain` × (−`standoff` − x_g)) m/s, slowing to a stop `standoff` in
front of the landing point (a vehicle held on the back bars presses on them, and the contact
chatters at the 50 ms step: 150-250 N peaks at 20 N mean; the docked conditions hold there), but never
beyond x + `guide_lead` (x: the vehicle's place along the axis) nor beyond −`approach_distance` ×
clip((m − `align_tolerance`) / (`align_limit` − `align_tolerance`), 0, 1), where `misalignment` m =
the vehicle's distance from the axis + `guide_heading_weight` × |heading error| (m, the heading
error in rad): it goes up to its stop while the vehicle is lined up (m ≤ `align_tolerance`)
and waits `approach_distance` in front of it while m ≥ `align_limit` (a misaligned vehicle in the
opening is led back out). The guide moves at a bounded speed, not a fixed lead ahead of the vehicle,
so that the observed integral of the error to it does not wind up on the way in (with a guide kept
ahead of the vehicle a PID hit the back bars at 0.2 m/s with 80-100 N). The position reward terms
see the distance along the route, |p − g| + |g − landing point|.

Observation: station keeping's (`station_keeping`) towards the guide point at heading 0, then `dock`
(the landing point minus the position, body frame, m), then the integral of the error to the guide
point. The evaluation window is the last second of the episode, as for station keeping; the
position error reported is the landing point's.
"""

from __future__ import annotations

import dataclasses
import math
import types

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.config import check_nonnegative, check_range
from marinejax.envs.base import EnvConfig, RewardConfig, distance_terms, heading_error
from marinejax.envs.station_keeping import StationKeeping
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler, quat_to_mat
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
    approach_distance: float = 1.2  # m in front of the landing point: where the guide waits for the vehicle to line up
    approach_speed: float = 0.4  # m/s: the guide's speed along the axis, far from the landing point
    guide_gain: float = 0.5  # 1/s: the guide's speed per m still to go, near the landing point
    guide_lead: float = 0.5  # m: how far ahead of the vehicle along the axis the guide goes at most
    standoff: float = 0.02  # m in front of the landing point: where the guide stops
    align_tolerance: float = 0.05  # m of misalignment up to which the guide goes to the landing point
    align_limit: float = 0.15  # m of misalignment from which the guide stays at approach_distance
    guide_heading_weight: float = 0.3  # m of misalignment per rad of heading error
    reward: RewardConfig = RewardConfig(impact=10.0, docked=1.0)

    def __post_init__(self):
        super().__post_init__()
        check_range("start_distance", self.start_distance, low=0.0)
        check_nonnegative(self, ("start_bearing", "start_depth", "dock_inside", "dock_tolerance", "dock_heading", "dock_speed",
                                 "dock_hold", "impact_threshold", "approach_distance", "approach_speed", "guide_gain",
                                 "guide_lead", "standoff", "align_tolerance", "guide_heading_weight"))
        if self.standoff >= self.dock_inside:
            raise UserError(f"config 'standoff' ({self.standoff} m) must be below 'dock_inside' ({self.dock_inside} m): "
                            "a vehicle at the guide's stop must count as inside")
        if self.align_limit <= self.align_tolerance:
            raise UserError(f"config 'align_limit' ({self.align_limit} m) must be above 'align_tolerance' ({self.align_tolerance} m)")
        if self.start_bearing > math.pi / 2:
            raise UserError(f"config 'start_bearing' must be at most pi/2 (in front of the opening), got {self.start_bearing}")


@struct.dataclass
class DockTask:
    position: jnp.ndarray  # (3,) m, world: the landing point
    yaw: jnp.ndarray  # () rad: the station's heading
    hold: jnp.ndarray  # () s: how long the docked conditions have held
    guide: jnp.ndarray  # () m: the guide point's place along the station's axis from the landing point


class Docking(StationKeeping):
    config_class = DockingConfig
    success_heading_deg = None  # `docked`, the task's own success, requires the heading within dock_heading
    success_flag = "docked"  # docked (held for dock_hold) at the episode's end
    error_units = types.MappingProxyType({**StationKeeping.error_units, "lateral_error": "m", "impact_force": "N", "docked": ""})
    success_threshold_m = 0.05

    def __init__(self, vehicle, config: DockingConfig):
        super().__init__(vehicle, config)
        if not self.plant.sys.contacts:
            raise UserError(f"the Docking task needs a scene with contacts (the station); scene {config.scene!r} has none")

    def _sample_task(self, rng):
        return DockTask(position=jnp.zeros(3), yaw=jnp.zeros(()), hold=jnp.zeros(()), guide=jnp.zeros(()))

    def fit_task(self, rng, task: DockTask, params, current, start: VehicleState) -> DockTask:
        """The guide starts at the start's projection on the axis, at most approach_distance in front."""
        return task.replace(guide=jnp.minimum((start.position - task.position)[0], -self.config.approach_distance))

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

    def _next_guide(self, vs: VehicleState, task: DockTask) -> jnp.ndarray:
        """The guide's place along the axis (m) after this step (module docstring)."""
        c = self.config
        offset = vs.position - task.position  # the station's axis is world x (its heading is 0)
        misalignment = jnp.linalg.norm(offset[1:]) + c.guide_heading_weight * jnp.abs(heading_error(vs.quaternion, task.yaw))
        gate = jnp.clip((misalignment - c.align_tolerance) / (c.align_limit - c.align_tolerance), 0.0, 1.0)
        speed = jnp.minimum(c.approach_speed, c.guide_gain * jnp.maximum(-c.standoff - task.guide, 0.0))
        ahead = jnp.minimum(task.guide + speed * c.control_dt, offset[0] + c.guide_lead)
        return jnp.minimum(ahead, -jnp.maximum(c.approach_distance * gate, c.standoff))

    def guide(self, task: DockTask) -> jnp.ndarray:
        """The guide point (m, world) on the station's axis."""
        return task.position + jnp.stack([task.guide, 0.0, 0.0])

    def route_distance(self, vs: VehicleState, task: DockTask) -> jnp.ndarray:
        """The distance (m) to the landing point through the guide point."""
        g = self.guide(task)
        return jnp.linalg.norm(g - vs.position) + jnp.linalg.norm(task.position - g)

    def task_observation_fields(self) -> dict[str, slice]:
        fields = super().task_observation_fields()
        end = fields["last_action"].stop
        return {**fields, "dock": slice(end, end + 3)}

    def observe(self, vs: VehicleState, info, action):
        task: DockTask = info["task"]
        to_landing = quat_to_mat(vs.quaternion).T @ (task.position - vs.position)
        return jnp.concatenate([self._pose_observation(vs, self.guide(task), task.yaw, action), to_landing])

    def integral_error(self, vs: VehicleState, info: dict) -> jnp.ndarray:
        task: DockTask = info["task"]
        return jnp.concatenate([self.guide(task) - vs.position, heading_error(vs.quaternion, task.yaw)[None]])

    def _docked_now(self, vs: VehicleState, task: DockTask) -> jnp.ndarray:
        c = self.config
        offset = vs.position - task.position  # the station's axis is world x (its heading is 0)
        return ((offset[0] >= -c.dock_inside) & (jnp.linalg.norm(offset[1:]) <= c.dock_tolerance)
                & (jnp.degrees(jnp.abs(heading_error(vs.quaternion, task.yaw))) <= c.dock_heading)
                & (jnp.linalg.norm(vs.velocity) <= c.dock_speed))

    def advance_task(self, task: DockTask, vs: VehicleState, info) -> DockTask:
        return task.replace(hold=jnp.where(self._docked_now(vs, task), task.hold + self.config.control_dt, 0.0),
                            guide=self._next_guide(vs, task))

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
        task: DockTask = info["task"]
        d = self.route_distance(vs, task)
        r = self.config.reward
        threshold = self.config.impact_threshold
        return {
            **super().reward_terms(vs, info, action),
            **distance_terms(d, r),
            "impact": -jnp.maximum(contact_force(info) - threshold, 0.0) / threshold,
            "docked": jnp.minimum(task.hold / self.config.dock_hold, 1.0),
        }


def contact_force(info) -> jnp.ndarray:
    """The magnitude (N) of the force the scene exerts on the vehicle (`info["contact"]`)."""
    return jnp.linalg.norm(info["contact"][:3])
