"""Altimeter: a DVL's bottom-lock beams, ranging to the seabed and whatever else lies below.

Beams (body frame FLU) tilted `beam_angle` from straight down, at azimuths 45°, 135°, 225° and
315° from forward for four beams (a Janus X, as the Water Linked A50), from the mount point
`position`. Each beam's range: the ray-cast distance plus white noise (std noise_floor +
noise_fraction · range), valid between `min_range` and `max_range` (an invalid beam reads
`max_range`); each update is lost with probability `dropout` (every beam invalid). The altitude is
the mean over the valid beams of range · cos(beam_angle), the distance along the DVL's axis as a
DVL reports it; with none valid it reads `max_range`. Bottom lock needs three valid beams (a
three-beam solution); without it a DVL has no velocity, and `SensorSuite` drops its velocity
updates (observation mode "sensors").

Defaults (Water Linked DVL A50 datasheet): 4 beams at 22.5°, altitude 0.05-50 m. Range noise,
update rate and dropout are assumed (the datasheet states velocity accuracy, not range accuracy).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.plant.rays import check_ray_sensor

_DEG = math.pi / 180.0


@dataclasses.dataclass(frozen=True)
class AltimeterConfig:
    enabled: bool = False
    ideal: bool = False  # True: exact ranges every control step, no noise or dropout
    position: tuple[float, float, float] = (0.0, 0.0, -0.15)  # m, body FLU: the transducer head
    beams: int = 4
    beam_angle: float = 22.5 * _DEG  # rad from straight down
    min_range: float = 0.05  # m
    max_range: float = 50.0  # m
    noise_floor: float = 0.01  # m, range std (assumed)
    noise_fraction: float = 0.005  # of the range (assumed)
    dropout: float = 0.02  # probability that an update is lost (assumed)
    rate_hz: float = 10.0  # (assumed; the A50 pings at 2-15 Hz depending on altitude)

    def __post_init__(self):
        check_ray_sensor("sensors.altimeter", self)

    @property
    def sensor(self) -> type:
        """The class that implements it (a scene sensor's config names it: `plant.scene_sensors`)."""
        return Altimeter


@struct.dataclass
class AltimeterReading:
    ranges: jnp.ndarray  # (beams,) m along each beam; max_range where invalid
    valid: jnp.ndarray  # (beams,) bool
    altitude: jnp.ndarray  # () m along the DVL's axis; max_range without a valid beam
    lock: jnp.ndarray  # () bool: at least 3 valid beams (all of them if fewer)


class Altimeter:
    """The beams of one vehicle's DVL; directions resolved here, `measure` pure."""

    observation_size = 1  # the altitude, m
    field = ("m", "body", "altitude along the DVL's axis from its beams (max_range without bottom lock)")

    def __init__(self, config: AltimeterConfig, control_dt: float):
        self.config = config
        c = config
        # one beam points straight down; several are spread evenly in azimuth from 45°
        angle = c.beam_angle if c.beams > 1 else 0.0
        az = (45.0 + 360.0 / c.beams * np.arange(c.beams)) * _DEG
        dirs = np.stack([math.sin(angle) * np.cos(az), math.sin(angle) * np.sin(az), -math.cos(angle) * np.ones(c.beams)], axis=-1)
        self.directions = jnp.asarray(dirs, jnp.float32)
        self._cos = math.cos(angle)
        self.mount = jnp.asarray(c.position, jnp.float32)
        self.period = 1 if c.ideal else max(1, round(1.0 / (c.rate_hz * control_dt)))

    def measure(self, cast, rng: jax.Array) -> AltimeterReading:
        """One ping: `cast(mount, directions, max_range)` is the scene's ray cast (`SceneRays.cast`
        bound to the vehicle's state)."""
        c = self.config
        dist, hit = cast(self.mount, self.directions, c.max_range)
        if not c.ideal:
            k_noise, k_drop = jax.random.split(rng)
            dist = dist + jax.random.normal(k_noise, dist.shape) * (c.noise_floor + c.noise_fraction * dist)
            hit = hit & (jax.random.uniform(k_drop) >= c.dropout)
        valid = hit & (dist >= c.min_range) & (dist <= c.max_range)
        ranges = jnp.where(valid, dist, c.max_range)
        n = jnp.sum(valid)
        altitude = jnp.where(n > 0, jnp.sum(jnp.where(valid, ranges, 0.0)) * self._cos / jnp.maximum(n, 1), c.max_range)
        return AltimeterReading(ranges=ranges, valid=valid, altitude=altitude, lock=n >= min(3, c.beams))

    def observe(self, reading: AltimeterReading) -> jnp.ndarray:
        return reading.altitude[None]
