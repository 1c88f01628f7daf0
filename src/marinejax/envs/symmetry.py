"""Mirror symmetry of an env: how its observation and action change when the world and the vehicle
are reflected through a vertical plane (y → −y in the world and in the body frame FLU).

A vehicle symmetric about its x–z plane that turns left in one situation turns right, the same way,
in its mirror image. A policy that knows this (`ppo.Config.mirror_symmetric`) learns both turning
directions as one: without it, PPO on the torpedo's circles sometimes learned one direction and
not the other (docs/results.md).

Under the reflection a vector (position, velocity, world up, path points) keeps x and z and negates
y; a pseudovector (angular velocity) negates x and z; a heading error or heading negates; speeds
and depths stay; actuator commands and states map by the vehicle's `action_mirror`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from marinejax.errors import UserError

_VECTOR, _PSEUDO = (1, -1, 1), (-1, 1, -1)
_SIN_COS = (-1, 1)  # sin and cos of an angle about z
# Per observation field (`base.OBSERVATION_FIELDS`): the signs of its components under the
# reflection, repeated over the field; "action": the vehicle's action mirror.
FIELD_SIGNS: dict[str, tuple[int, ...] | str] = {
    "position_error": _VECTOR, "reference_ahead": _VECTOR, "reference_velocity": _VECTOR, "path_ahead": _VECTOR,
    "tangent": _VECTOR, "up": _VECTOR, "velocity": _VECTOR, "dock": _VECTOR, "integral_position": _VECTOR,
    "angular_velocity": _PSEUDO,
    "depth_error": (1,), "speed_error": (1,), "set_point_depth": (1,), "set_point_speed": (1,),
    "altitude_error_ahead": (1,), "distance_ahead": (1,),
    "set_point_heading": _SIN_COS, "heading": _SIN_COS, "integral_heading": (-1,),
    "actuators": "action", "last_action": "action",
}
_WRENCH_SIGNS = np.array([1, -1, 1, -1, 1, -1], np.float32)  # [F; M] in the body frame


@dataclasses.dataclass(frozen=True, eq=False)
class Mirror:
    """The reflection as signed permutations: observation' = observation[obs_perm] * obs_sign and
    action' = action[action_perm] * action_sign (each its own inverse)."""

    obs_perm: np.ndarray  # (obs,) int
    obs_sign: np.ndarray  # (obs,) float32, ±1
    action_perm: np.ndarray  # (action,) int
    action_sign: np.ndarray  # (action,) float32, ±1

    def observation(self, obs):
        return obs[..., self.obs_perm] * self.obs_sign

    def action(self, action):
        return action[..., self.action_perm] * self.action_sign


def env_mirror(env) -> Mirror:
    """The `Mirror` of env `env` (a `MarineEnv`), from its observation fields and its vehicle's
    actuators; raises UserError naming the fields that have no mirror image (e.g. a sonar fan)."""
    if env.config.action_mode == "wrench":
        action_perm, action_sign = np.arange(6), _WRENCH_SIGNS
    else:
        action_perm, action_sign = env.vehicle.action_mirror()
    fields = env.observation_fields()
    unknown = sorted(name for name in fields if name not in FIELD_SIGNS)
    if unknown:
        raise UserError(f"{type(env).__name__}: observation fields {unknown} have no mirror image; mirror symmetry "
                        f"covers {sorted(FIELD_SIGNS)}")
    size = env.observation_size if isinstance(env.observation_size, int) else env.observation_size["state"][0]
    covered = np.zeros(size, bool)
    for sl in fields.values():
        covered[sl] = True
    if not covered.all():
        raise UserError(f"{type(env).__name__}: observation components {np.flatnonzero(~covered).tolist()} belong to no field")
    perm, sign = np.arange(size), np.ones(size, np.float32)
    for name, sl in fields.items():
        rule = FIELD_SIGNS[name]
        if rule == "action":
            perm[sl] = sl.start + action_perm
            sign[sl] = action_sign
        else:
            n = sl.stop - sl.start
            if n % len(rule):
                raise UserError(f"observation field {name!r} has {n} components, not a multiple of {len(rule)}")
            sign[sl] = np.tile(np.asarray(rule, np.float32), n // len(rule))
    return Mirror(obs_perm=perm, obs_sign=sign, action_perm=np.asarray(action_perm), action_sign=np.asarray(action_sign, np.float32))
