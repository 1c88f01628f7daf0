"""A constant external force and torque per episode: what a tether, a payload or a mis-trimmed
vehicle does to a controller that has no integral action.

Drawn per episode (`Plant.sample_params`, into `PlantParams.disturbance`) when `disturbance.enabled`: a world-frame force with magnitude uniform in `force`
(N) and a uniformly random direction in 3-D, and a body-frame torque about the centre of gravity
with magnitude uniform in `torque` (N m) and a uniformly random axis. Both stay constant over the
episode. `Plant.step` converts the force into the body frame at the start of every control step
and hands the body wrench to the physics with the thrust.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from marinejax.config import check_range


@dataclasses.dataclass(frozen=True)
class DisturbanceConfig:
    enabled: bool = False
    force: tuple[float, float] = (0.0, 4.0)  # N, magnitude of the world-frame force
    torque: tuple[float, float] = (0.0, 0.4)  # N m, magnitude of the body-frame torque

    def __post_init__(self):
        check_range("disturbance.force", self.force, low=0.0)
        check_range("disturbance.torque", self.torque, low=0.0)


def _random_unit(rng: jax.Array) -> jnp.ndarray:
    v = jax.random.normal(rng, (3,))
    return v / jnp.maximum(jnp.linalg.norm(v), 1e-9)


def sample_disturbance(rng: jax.Array, config: DisturbanceConfig) -> jnp.ndarray:
    """(6,) [world-frame force (N), body-frame torque (N m)] of an episode; zeros when disabled."""
    if not config.enabled:
        return jnp.zeros(6)
    k = jax.random.split(rng, 4)
    force = jax.random.uniform(k[0], minval=config.force[0], maxval=config.force[1]) * _random_unit(k[1])
    torque = jax.random.uniform(k[2], minval=config.torque[0], maxval=config.torque[1]) * _random_unit(k[3])
    return jnp.concatenate([force, torque])


def body_wrench(disturbance: jnp.ndarray, rot: jnp.ndarray) -> jnp.ndarray:
    """The disturbance as a body-frame wrench (6,); rot: (3, 3) body → world."""
    return jnp.concatenate([rot.T @ disturbance[:3], disturbance[3:]])
