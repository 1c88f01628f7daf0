"""Ocean current per episode: off, constant, or Ornstein-Uhlenbeck around the episode's mean.

The current is a world-frame velocity (m/s), uniform in space. Its mean is drawn per episode:
speed uniform in `speed`, azimuth uniform, elevation uniform in ±`max_elevation_deg` (3-D).
The OU step x' = x̄ + e^(−μΔt)(x − x̄) + σ sqrt(1 − e^(−2μΔt)) ξ is exact, so the process has
stationary standard deviation σ per axis whatever the step Δt (Fossen's slowly varying current).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.config import check_range
from marinejax.errors import UserError

CURRENT_MODES = ("off", "constant", "ou")


@dataclasses.dataclass(frozen=True)
class CurrentConfig:
    mode: str = "off"  # off | constant | ou
    speed: tuple[float, float] = (0.0, 0.3)  # m/s, range of the episode's mean speed
    max_elevation_deg: float = 15.0  # deg, |elevation| of the mean direction above/below horizontal
    ou_rate: float = 0.1  # μ, 1/s: how fast the current returns to its mean
    ou_sigma: float = 0.05  # σ, m/s: stationary standard deviation per axis around the mean

    def __post_init__(self):
        if self.mode not in CURRENT_MODES:
            raise UserError(f"config 'current.mode' must be one of {list(CURRENT_MODES)}, got {self.mode!r}")
        check_range("current.speed", self.speed, low=0.0)
        if not 0 <= self.max_elevation_deg <= 90:
            raise UserError(f"config 'current.max_elevation_deg' must be in [0, 90], got {self.max_elevation_deg}")
        if self.ou_rate <= 0 or self.ou_sigma < 0:
            raise UserError(f"config 'current.ou_rate' must be > 0 and 'current.ou_sigma' >= 0, got {self.ou_rate}, {self.ou_sigma}")


@struct.dataclass
class CurrentState:
    mean: jnp.ndarray  # (3,) m/s, world frame: the episode's mean current
    value: jnp.ndarray  # (3,) m/s, world frame: the current now


def sample_current(rng: jax.Array, config: CurrentConfig) -> CurrentState:
    """Draw an episode's current (zero when mode is 'off'). In 'ou' mode it starts at its mean."""
    if config.mode == "off":
        zero = jnp.zeros(3)
        return CurrentState(mean=zero, value=zero)
    k1, k2, k3 = jax.random.split(rng, 3)
    speed = jax.random.uniform(k1, minval=config.speed[0], maxval=config.speed[1])
    azimuth = jax.random.uniform(k2, minval=-math.pi, maxval=math.pi)
    el = math.radians(config.max_elevation_deg)
    elevation = jax.random.uniform(k3, minval=-el, maxval=el)
    mean = speed * jnp.array(
        [jnp.cos(elevation) * jnp.cos(azimuth), jnp.cos(elevation) * jnp.sin(azimuth), jnp.sin(elevation)]
    )
    return CurrentState(mean=mean, value=mean)


def step_current(state: CurrentState, rng: jax.Array, dt: float, config: CurrentConfig) -> CurrentState:
    """Advance the current by dt seconds (unchanged unless mode is 'ou')."""
    if config.mode != "ou":
        return state
    decay = math.exp(-config.ou_rate * dt)
    noise = config.ou_sigma * math.sqrt(1.0 - decay**2) * jax.random.normal(rng, (3,))
    return state.replace(value=state.mean + decay * (state.value - state.mean) + noise)
