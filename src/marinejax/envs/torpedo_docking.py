"""Torpedo docking: fly a torpedo AUV down the approach line into the funnel dock of the
`torpedo_dock` scene until its nose is latched inside the dock's tube.

The dock is the scene's, fixed (`models/scenes/torpedo_dock.xml`): its axis along world +x through
the origin, a cone of guide bars from a 1 m mouth at x = 0 to a tube of inner radius 0.20 m from
x = `tube_entrance` (1 m) on. The approach line is that axis; it is path following (`path_following`)
on a straight path that starts `start_distance` m before the mouth: the same observation (so the
line-of-sight autopilot flies it), plus where the latch point is. The vehicle starts up to
`start_offset` m off the line sideways (half that vertically), heading within ±`start_heading_error`
rad of it, under way at the commanded speed (`path.speed`, drawn per episode).

Latched (the metric `docked`, 1 or 0, and the task's state): once the vehicle's nose (`nose`, body
frame from the CG) is past the tube's entrance and within `capture_radius` of the axis, the dock's
latch holds it: the task is done, its errors are 0 and its reward is the best of every term plus
`reward.docked` per step for the rest of the episode (the physics goes on; a real dock would stop
the vehicle, and nothing the vehicle does then counts). Contacts with the funnel are how it guides
the vehicle; a contact force above `impact_threshold` N is an impact, penalized by the reward term
`impact` (−(|F| − threshold)/threshold) and logged as `impact_force` (N).

Errors: `position_error` is the nose's distance from the latch point (the tube's entrance on the
axis) on the way in, 0 once latched, and for a vehicle whose nose passed the entrance's plane
without being latched (outside the tube: a miss it cannot turn back from) its distance from the axis
there, from then on. Over the evaluation window, the last second, it is 0 for a docked episode, the
miss distance for a missed one and the distance still to go for one that did not arrive, so the
success rate (below `success_threshold_m`) is the docking rate;
`cross_track_error` is the CG's distance from the approach line; `heading_error_deg` and
`speed_error` are path following's. The episode ends beyond `max_distance` m of the latch point.

Observation: path following's (`path_following`: the closest point of the line, the line ahead, the
tangent, the commanded speed and its error, attitude, velocities, actuators, last action), then
`dock`: the latch point minus the nose (m, body frame), then the integral of the cross-track error.
"""

from __future__ import annotations

import dataclasses
import types

import jax
import jax.numpy as jnp
from flax import struct

import marinejax.envs.paths as paths
from marinejax.config import check_nonnegative, check_range
from marinejax.envs.base import RewardConfig
from marinejax.envs.docking import contact_force
from marinejax.envs.path_following import PathFollowing, PathFollowingConfig
from marinejax.errors import UserError
from marinejax.frames import quat_to_mat
from marinejax.physics import VehicleState


@dataclasses.dataclass(frozen=True)
class TorpedoDockingConfig(PathFollowingConfig):
    scene: str = "torpedo_dock"
    episode_length: int = 600  # 60 s at 10 Hz: 41 m at 1 m/s, with 19 s to spare
    max_distance: float = 60.0  # m, the nose from the latch point: the episode terminates beyond
    start_distance: tuple[float, float] = (20.0, 40.0)  # m before the dock's mouth, along its axis
    start_offset: float = 2.0  # m off the approach line sideways (vertically: half)
    start_heading_error: float = 0.2  # rad
    path: paths.PathConfig = paths.PathConfig(speed=(1.0, 1.5))  # m/s: the approach speed
    nose: tuple[float, float, float] = (0.8, 0.0, 0.02)  # m, body frame FLU from the CG: the REMUS 100's
    tube_entrance: float = 1.0  # m along the dock's axis (the scene's)
    capture_radius: float = 0.115  # m, the nose from the axis: the tube's 0.20 m less the hull's 0.095, plus 1 cm
    impact_threshold: float = 200.0  # N: the funnel's bars turning a 1.5 m/s vehicle push with up to ~100 N
    reward: RewardConfig = RewardConfig(upright=0.0, speed=1.0, impact=1.0, docked=5.0)

    def __post_init__(self):
        super().__post_init__()
        check_range("start_distance", self.start_distance, positive=True)
        check_nonnegative(self, ("tube_entrance", "capture_radius", "impact_threshold"))


@struct.dataclass
class DockApproachTask:
    path: paths.Legs  # the approach line: one straight along +x, from start_distance m before the mouth
    speed: jnp.ndarray  # () m/s, commanded
    s: jnp.ndarray  # () m, arc length of the closest point
    along_speed: jnp.ndarray  # () m/s, ds/dt over the last step
    yaw: jnp.ndarray  # () rad, the line's heading (0)
    docked: jnp.ndarray  # () 1.0 once latched
    miss: jnp.ndarray  # () m: the nose's distance from the axis where it passed the entrance unlatched; −1 before


class TorpedoDocking(PathFollowing):
    config_class = TorpedoDockingConfig
    error_units = types.MappingProxyType({"heading_error_deg": "deg", "position_error": "m", "speed_error": "m/s",
                                          "cross_track_error": "m", "impact_force": "N", "docked": ""})
    error_window_description = "the last second"
    success_threshold_m = 0.1

    def __init__(self, vehicle, config: TorpedoDockingConfig):
        super().__init__(vehicle, config, kind="lines")
        if not self.plant.sys.contacts:
            raise UserError(f"the TorpedoDocking task needs a scene with contacts (the dock); scene {config.scene!r} has none")
        self._nose = jnp.asarray(config.nose, jnp.float32)
        self._latch = jnp.array([config.tube_entrance, 0.0, 0.0], jnp.float32)

    def error_window(self, time):
        return self.after(time, self.config.episode_length * self.config.control_dt - 1.0)

    def _sample_task(self, rng):
        k1, k2 = jax.random.split(rng)
        c = self.config
        distance = jax.random.uniform(k1, minval=c.start_distance[0], maxval=c.start_distance[1])
        line = paths.Legs(start_s=jnp.zeros(1), start=jnp.array([[-1.0, 0.0, 0.0]]) * distance, direction=jnp.array([[1.0, 0.0, 0.0]]),
                          center=jnp.zeros((1, 3)), angle=jnp.zeros(1), side=jnp.ones(1), radius=jnp.asarray(c.path.fillet_radius, jnp.float32))
        speed = jax.random.uniform(k2, minval=c.path.speed[0], maxval=c.path.speed[1])
        return DockApproachTask(path=line, speed=speed, s=jnp.zeros(()), along_speed=speed, yaw=jnp.zeros(()),
                                docked=jnp.zeros(()), miss=-jnp.ones(()))

    def nose(self, vs: VehicleState) -> jnp.ndarray:
        """The nose's position (m, world)."""
        return vs.position + quat_to_mat(vs.quaternion) @ self._nose

    def advance_task(self, task: DockApproachTask, vs: VehicleState) -> DockApproachTask:
        task = super().advance_task(task, vs)
        nose = self.nose(vs)
        radial = jnp.linalg.norm(nose[1:])
        through = nose[0] >= self.config.tube_entrance
        latched = through & (radial <= self.config.capture_radius) & (task.miss < 0)
        missed = through & ~latched & (task.docked == 0) & (task.miss < 0)
        return task.replace(docked=jnp.maximum(task.docked, latched.astype(jnp.float32)), miss=jnp.where(missed, radial, task.miss))

    def errors(self, vs: VehicleState, info) -> dict[str, jnp.ndarray]:
        task: DockApproachTask = info["task"]
        free = 1.0 - task.docked
        follow = super().errors(vs, info)
        return {
            "heading_error_deg": follow["heading_error_deg"] * free,
            "position_error": jnp.where(task.miss >= 0, task.miss, jnp.linalg.norm(self._latch - self.nose(vs))) * free,
            "speed_error": follow["speed_error"] * free,
            "cross_track_error": follow["position_error"] * free,
            "impact_force": contact_force(info),
            "docked": task.docked,
        }

    def task_observation_fields(self) -> dict[str, slice]:
        fields = super().task_observation_fields()
        end = fields["last_action"].stop
        return {**fields, "dock": slice(end, end + 3)}

    def observe(self, vs: VehicleState, info, action):
        to_latch = quat_to_mat(vs.quaternion).T @ (self._latch - self.nose(vs))
        return jnp.concatenate([super().observe(vs, info, action), to_latch])

    def reward_terms(self, vs: VehicleState, info, action):
        task: DockApproachTask = info["task"]
        threshold = self.config.impact_threshold
        terms = {**super().reward_terms(vs, info, action), "impact": -jnp.maximum(contact_force(info) - threshold, 0.0) / threshold,
                 "docked": task.docked}
        # latched: the best value of every term (1 for the bounded ones, 0 for the penalties)
        best = {"position": 1.0, "precision": 1.0, "speed": 1.0, "heading": 1.0, "docked": 1.0}
        return {k: jnp.where(task.docked > 0, best.get(k, 0.0), v) for k, v in terms.items()}
