"""Forward-looking multibeam imaging sonar: a fan of beams giving a range image.

An imaging sonar resolves bearing (its beams across the horizontal aperture) and range, but not
elevation: each beam insonifies a vertical slice `vertical_fov` wide and returns the nearest echo in
it. Modelled by `rows` rays per beam spread over the vertical aperture, the beam's range being the
nearest of them. Fan centred on the body x axis, pitched down by `tilt`, from the mount point
`position` (body FLU). Per beam: range plus white noise (std `range_noise`), quantised into range
bins of `range_resolution`, blind below `min_range` (reads `min_range`), nothing within `max_range`
reads `max_range` with `hit` False, and a beam is lost with probability `dropout` per ping (reads
`max_range`, `hit` False).

Defaults: the aperture of an Oculus M750d (Blue Print Subsea datasheet: 130° × 20°, 512 beams, up
to 120 m at 750 kHz), sampled by 32 beams of one ray each (4.2° apart, at the aperture's centre)
and 0.2-20 m of range; range noise, bins, dropout and the 10 Hz ping rate are assumed. The cost is
the ray casts, linear in rays × seen geoms (about 0.7 µs per ray among 13 capsules on this 2-core
CPU): 32 rays keep an env at about 30 % of its sonar-free rate at batch 1024, 64 × 4 rays at 4 %
(`marinejax bench envs --with sensors.sonar.enabled=true`); `beams` and `rows` buy resolution
and the vertical aperture at that price.

Echo intensity (`intensity=True`): each beam also reports the strength of its echo by Lambert's
law of seafloor backscatter, cos² of the incidence angle (Mackenzie 1961, J. Acoust. Soc. Am. 33:
1498), 1 for a surface met head on, 0 for a grazing one or no echo; the surface normal comes from
the hit geom's shape at the hit point (`SceneRays.cast(incidence=True)`; primitive geoms only). Of a
beam's rows, the nearest echo's. Spreading and absorption losses are taken as compensated by the
sonar's time-varied gain, materials as alike; the image has no speckle. The observation then holds
the ranges (field `sonar`), then the intensities (field `sonar_intensity`).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.plant.rays import check_ray_sensor, fan, spread

_DEG = math.pi / 180.0


@dataclasses.dataclass(frozen=True)
class SonarConfig:
    enabled: bool = False
    ideal: bool = False  # True: exact ranges every control step, no noise, bins or dropout
    position: tuple[float, float, float] = (0.25, 0.0, 0.0)  # m, body FLU: the transducer
    tilt: float = 10.0 * _DEG  # rad, the fan's centre below the body x axis
    beams: int = 32  # across the horizontal aperture
    horizontal_fov: float = 130.0 * _DEG  # rad
    rows: int = 1  # rays per beam across the vertical aperture (1: its centre only)
    vertical_fov: float = 20.0 * _DEG  # rad
    min_range: float = 0.2  # m
    max_range: float = 20.0  # m
    range_noise: float = 0.02  # m, std (assumed)
    range_resolution: float = 0.01  # m, bin width; 0: not quantised (assumed)
    dropout: float = 0.01  # probability per beam and ping (assumed)
    rate_hz: float = 10.0  # (assumed)
    intensity: bool = False  # True: each beam's echo intensity too (Lambert's law), observed after the ranges (`sonar_intensity`)

    def __post_init__(self):
        check_ray_sensor("sensors.sonar", self, counts=("beams", "rows"))

    @property
    def sensor(self) -> type:
        """The class that implements it (a scene sensor's config names it: `plant.scene_sensors`)."""
        return Sonar


@struct.dataclass
class SonarReading:
    ranges: jnp.ndarray  # (beams,) m, from the right edge of the fan (azimuth −fov/2) to the left
    hit: jnp.ndarray  # (beams,) bool: an echo within max_range
    intensity: jnp.ndarray  # (beams,) in [0, 1]: cos² of the incidence angle (0: no echo; 0 everywhere unless `intensity`)


class Sonar:
    """The fan of one vehicle's sonar; directions resolved here, `measure` pure."""

    field = ("m", "body", "sonar range per beam, right to left across the fan (max_range: no echo)")
    intensity_field = ("1", "body", "sonar echo intensity per beam, right to left (cos² of the incidence angle; 0: no echo)")

    def __init__(self, config: SonarConfig, control_dt: float):
        self.config = config
        c = config
        self.incidence = c.intensity  # whether it needs the incidence angle of its rays (`Plant`)
        # with intensities, two observation fields: the ranges ("sonar"), then the intensities
        self.fields = {"sonar": (c.beams, self.field), "sonar_intensity": (c.beams, self.intensity_field)} if c.intensity else None
        self.directions = jnp.asarray(fan(c.beams, c.horizontal_fov, c.rows, c.vertical_fov, c.tilt))
        self.azimuth = spread(c.beams, c.horizontal_fov)  # (beams,) rad, body, positive to the left
        self.mount = jnp.asarray(c.position, jnp.float32)
        self.period = 1 if c.ideal else max(1, round(1.0 / (c.rate_hz * control_dt)))
        self.observation_size = c.beams * (2 if c.intensity else 1)  # the range image (m), and the intensities

    def measure(self, cast, rng: jax.Array) -> SonarReading:
        """One ping: `cast(mount, directions, max_range)` is the scene's ray cast (`SceneRays.cast`
        bound to the vehicle's state)."""
        c = self.config
        if c.intensity:
            dist, hit, cos = cast(self.mount, self.directions, c.max_range, incidence=True)
            nearest = jnp.argmin(dist, axis=-1)[..., None]
            intensity = jnp.take_along_axis(cos, nearest, axis=-1)[..., 0] ** 2  # of the nearest echo in the beam's slice
        else:
            dist, hit = cast(self.mount, self.directions, c.max_range)
        dist, hit = jnp.min(dist, axis=-1), jnp.any(hit, axis=-1)  # the nearest echo in each beam's slice
        if not c.ideal:
            k_noise, k_drop = jax.random.split(rng)
            dist = dist + jax.random.normal(k_noise, dist.shape) * c.range_noise
            if c.range_resolution > 0:
                dist = jnp.round(dist / c.range_resolution) * c.range_resolution
            hit = hit & (jax.random.uniform(k_drop, dist.shape) >= c.dropout)
        ranges = jnp.where(hit, jnp.clip(dist, c.min_range, c.max_range), c.max_range)
        intensity = jnp.where(hit, intensity, 0.0) if c.intensity else jnp.zeros_like(ranges)
        return SonarReading(ranges=ranges, hit=hit, intensity=intensity)

    def observe(self, reading: SonarReading) -> jnp.ndarray:
        return jnp.concatenate([reading.ranges, reading.intensity]) if self.config.intensity else reading.ranges
