"""What the tasks of vehicles that cannot hover (torpedo AUVs) share: a start under way, with the
propeller already turning, and the actuator states in the observation.

Such a vehicle steers with fins that only work while it moves, so every episode starts at speed;
its actuators' states (fin angles, shaft speed) lag their commands by up to a second and are part
of what the policy must see.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from marinejax.actuators import state_ranges
from marinejax.envs.base import EnvConfig, MarineEnv
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler
from marinejax.physics import VehicleState
from marinejax.plant import CurrentConfig, RandomizationConfig


@dataclasses.dataclass(frozen=True)
class CruisingConfig(EnvConfig):
    """What the torpedo tasks share: an AUV autopilot's rate, the start's shaft speed, currents of up
    to 0.5 m/s when on."""

    control_dt: float = 0.1  # s: 10 Hz, an AUV autopilot's rate
    substeps: int = 2  # two 50 ms physics steps per action
    top_speed: float = 2.554  # m/s at full propeller command (the REMUS 100's): the start's shaft speed, linear in speed
    # m/s, used when current.mode is not "off" (Disturbed). Horizontal: ocean currents are, to within
    # mm/s, and a torpedo slow through the water cannot hold a depth under a current sinking at 15°
    # (0.13 m/s at 0.5 m/s): the REMUS 100 with its stern planes at the limit climbs at most 0.04 m/s
    # at 0.75 m/s. The disturbed autopilot's seeds 0-4 reached 0.27-0.44 m of depth error with 15°,
    # 0.09-0.12 m with 0° (docs/results.md).
    current: CurrentConfig = CurrentConfig(speed=(0.0, 0.5), max_elevation_deg=0.0)
    # A torpedo is ballasted to trim: its centre of buoyancy drawn within ±1 mm of the nominal (about
    # 3° of pitch or roll with the REMUS 100's 2 cm BG), not the ROVs' ±5 mm (14°), which takes most
    # of the stern planes' moment at 1 m/s and has no actuator at all in roll: with it, a REMUS at
    # 1.2 m/s could neither climb (stern planes pinned at their limit) nor hold a turn (docs/results.md).
    randomization: RandomizationConfig = RandomizationConfig(cob_offset=0.001)

    def __post_init__(self):
        super().__post_init__()
        if not self.top_speed > 0:
            raise UserError(f"config 'top_speed' must be > 0, got {self.top_speed}")


def current_margin(config: CruisingConfig) -> float:
    """m/s added to the mean current's horizontal speed for the OU current's wander (two standard deviations)."""
    return 2.0 * 2.0**0.5 * config.current.ou_sigma if config.current.mode == "ou" else 0.0


def current_drift(config: CruisingConfig, current_mean: jnp.ndarray) -> jnp.ndarray:
    """m/s: the horizontal speed of the episode's mean current ((3,) m/s, world) plus `current_margin`;
    0 with the current off."""
    if config.current.mode == "off":
        return jnp.zeros(())
    return jnp.linalg.norm(current_mean[:2]) + current_margin(config)


def speeds_through_water(config: CruisingConfig, speed: jnp.ndarray, drift: jnp.ndarray) -> jnp.ndarray:
    """Speed set-points over the ground (m/s) drawn within `config.speed_range` = (lo, hi), mapped
    into [lo + drift, hi − drift] (`drift`, m/s: `current_drift`), so that the speed through the
    water stays within (lo, hi) whatever the heading."""
    lo, hi = config.speed_range
    return lo + drift + (speed - lo) * ((hi - lo - 2 * drift) / (hi - lo) if hi > lo else 0.0)


def weakest_fins(config: CruisingConfig) -> float:
    """The lowest fin lift factor the randomization draws (1 without randomization): the episode's
    true fins are unknown to whoever plans its task, their lower bound is not."""
    return min(1.0, config.randomization.fin_lift_scale[0]) if config.randomization.enabled else 1.0


class CruisingEnv(MarineEnv):
    """Base of the torpedo tasks (their configs are `CruisingConfig`s)."""

    vehicle_kinds = ("torpedo",)

    def __init__(self, vehicle, config):
        super().__init__(vehicle, config)
        groups = self.plant.sys.actuators
        # actuator states scaled by their command range, for the observation (looked up once)
        lo, hi = state_ranges(groups)
        self._act_lo, self._act_hi = jnp.asarray(np.float32(lo)), jnp.asarray(np.float32(hi))
        self._act_mid, self._act_half = jnp.asarray(np.float32((lo + hi) / 2)), jnp.asarray(np.float32((hi - lo) / 2))
        kinds = np.concatenate([[g.kind.name] * g.size for g in groups])
        self._propeller = jnp.asarray(kinds == "propeller")
        if not np.any(kinds == "propeller"):
            raise UserError(f"the {type(self).__name__} task needs a propeller; {self.vehicle.name!r} has actuator kinds {sorted(set(kinds))}")

    def scaled_actuators(self, vs: VehicleState) -> jnp.ndarray:
        """The actuator states, each scaled to [−1, 1] by its command range."""
        return (vs.actuators - self._act_mid) / self._act_half

    def cruising_state(self, position, roll_pitch_yaw, speed, velocity=None) -> VehicleState:
        """At `position` (m, world), attitude (rad), moving forward through the water at `speed` (m/s):
        the propeller at about that speed's shaft speed (linear in speed up to `config.top_speed`),
        fins at 0. `velocity`: the velocity over the ground (m/s, body frame), by default (speed, 0, 0),
        the velocity through still water."""
        shaft = self._act_lo + jnp.clip(speed / self.config.top_speed, 0.0, 1.0) * (self._act_hi - self._act_lo)
        return VehicleState(position=position, quaternion=quat_from_euler(*roll_pitch_yaw),
                            velocity=jnp.array([1.0, 0.0, 0.0]) * speed if velocity is None else velocity,
                            angular_velocity=jnp.zeros(3), actuators=jnp.where(self._propeller, shaft, 0.0))
