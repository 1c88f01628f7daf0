"""Reference paths for tracking tasks: circle, helix and lemniscate, as pure JAX functions of time.

World frame, z up, SI units (m, s, rad). A path is drawn per episode (`sample_params`) and then
evaluated at any time (`reference`), jit- and vmap-able; the velocity returned is the exact time
derivative of the position (forward-mode `jax.jvp`), not a finite difference.

Every path is traversed at a constant speed along the 3-D path after a linear ramp from rest, so the
reference starts where the vehicle starts and never asks for a step in velocity:
    s(t) = speed · t² / (2 ramp)   for t < ramp,    speed · (t − ramp/2)   after.

Default ranges: 0.2–0.5 m/s along paths of 1–2 m radius (lemniscate half-width). A BlueROV2 tops out
near 0.9 m/s in still water, and a tracking vehicle needs margin to correct errors, fight a current
and turn (centripetal 0.25 m/s² at 0.5 m/s on a 1 m circle); MarineGym's 0.7–2.4 m/s references are
faster than the vehicle can go.

Shapes:
  circle      horizontal, radius `size`, angle 2π·phase + direction·s/size (+ heading) about `center`.
  helix       the same circle in plan view, descending `pitch` m per turn from `center` z (negative pitch
              ascends); the speed is split so the 3-D speed is `speed`.
  lemniscate  of Bernoulli, (x, y) = a (cos τ, sin τ cos τ)/(1 + sin² τ), a = `size`: x ∈ [−a, a],
              y ∈ ±a/(2√2); rotated by `heading` about world z and shifted by `center`. Constant speed
              comes from an arc-length table (numpy, built once) mapping s to τ by cubic Hermite
              interpolation with the exact slopes dτ/ds = sqrt(1 + sin² τ)/a (speed ripple ~1e-7 in float64,
              ~1e-6 in float32; velocity continuous); direction +1 goes round the x > 0 lobe
              counter-clockwise seen from above (and the other lobe clockwise).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.config import check_range
from marinejax.errors import UserError

KINDS = ("circle", "helix", "lemniscate")

_LEMNISCATE_TABLE_SIZE = 1024  # segments of the s -> τ table (cubic Hermite, exact node slopes)


def _check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise UserError(f"unknown trajectory kind {kind!r}; valid kinds: {list(KINDS)}")


@dataclasses.dataclass(frozen=True)
class TrajectoryConfig:
    """Per-episode path distribution; each (low, high) range is drawn uniformly."""

    speed: tuple[float, float] = (0.2, 0.5)  # m/s along the path (constant after the ramp)
    size: tuple[float, float] = (1.0, 2.0)  # m: circle/helix radius; lemniscate half-width a
    helix_pitch: tuple[float, float] = (0.3, 0.6)  # m of descent per turn (helix only)
    center_xy: float = 0.0  # m: centre x and y each uniform in [-center_xy, center_xy]
    center_z: tuple[float, float] = (-5.0, -5.0)  # m, world z up (negative = below the surface)
    ramp_time: float = 2.0  # s: speed ramps linearly from 0 to full over this time
    random_direction: bool = True  # clockwise or counter-clockwise drawn per episode (else +1)
    random_phase: bool = True  # start point uniform along the path (else phase 0)
    random_heading: bool = True  # lemniscate: figure rotated about world z by a uniform angle (else 0)

    def __post_init__(self):
        check_range("trajectory.speed", self.speed, positive=True)
        check_range("trajectory.size", self.size, positive=True)
        check_range("trajectory.helix_pitch", self.helix_pitch)
        check_range("trajectory.center_z", self.center_z)
        if not (math.isfinite(self.center_xy) and self.center_xy >= 0):
            raise UserError(f"config 'trajectory.center_xy' must be finite and >= 0, got {self.center_xy!r}")
        if not (math.isfinite(self.ramp_time) and self.ramp_time >= 0):
            raise UserError(f"config 'trajectory.ramp_time' must be finite and >= 0, got {self.ramp_time!r}")


@struct.dataclass
class TrajectoryParams:
    """One episode's path (leaves may carry a leading batch axis; use vmap to evaluate a batch)."""

    center: jnp.ndarray  # (3,) m, world frame
    size: jnp.ndarray  # () m: radius, or lemniscate half-width
    speed: jnp.ndarray  # () m/s along the path after the ramp
    pitch: jnp.ndarray  # () m of descent per turn (helix; 0 otherwise)
    direction: jnp.ndarray  # () +1 counter-clockwise seen from above, -1 clockwise
    phase: jnp.ndarray  # () start point as a fraction in [0, 1) of one lap
    heading: jnp.ndarray  # () rad, rotation of the figure about world z (lemniscate; 0 otherwise)
    ramp_time: jnp.ndarray  # () s


def sample_params(kind: str, rng: jax.Array, config: TrajectoryConfig) -> TrajectoryParams:
    """Draw one episode's path of `kind` (static under jit) from `config`."""
    _check_kind(kind)
    k_speed, k_size, k_pitch, k_xy, k_z, k_dir, k_phase, k_head = jax.random.split(rng, 8)
    f = jnp.result_type(float)

    def uniform(key, lo_hi, shape=()):
        return jax.random.uniform(key, shape, f, minval=lo_hi[0], maxval=lo_hi[1])

    xy = uniform(k_xy, (-config.center_xy, config.center_xy), (2,))
    center = jnp.concatenate([xy, uniform(k_z, config.center_z, (1,))])
    zero = jnp.zeros((), f)
    pitch = uniform(k_pitch, config.helix_pitch) if kind == "helix" else zero
    if config.random_direction:
        direction = jnp.where(jax.random.bernoulli(k_dir), 1.0, -1.0).astype(f)
    else:
        direction = jnp.ones((), f)
    phase = jax.random.uniform(k_phase, (), f) if config.random_phase else zero
    if kind == "lemniscate" and config.random_heading:
        heading = jax.random.uniform(k_head, (), f, minval=0.0, maxval=2 * jnp.pi)
    else:
        heading = zero
    return TrajectoryParams(
        center=center,
        size=uniform(k_size, config.size),
        speed=uniform(k_speed, config.speed),
        pitch=pitch,
        direction=direction,
        phase=phase,
        heading=heading,
        ramp_time=jnp.asarray(config.ramp_time, f),
    )


@functools.cache
def _lemniscate_table() -> tuple[np.ndarray, np.ndarray, float]:
    """τ and dτ/ds at equally spaced arc length over one lap of the unit lemniscate, and its length (m).

    |dP/dτ| = 1/sqrt(1 + sin² τ) for a = 1; its periodic trapezoid integral converges spectrally.
    """
    tau = np.linspace(0.0, 2 * np.pi, (1 << 16) + 1)
    ds = 1.0 / np.sqrt(1.0 + np.sin(tau) ** 2)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (ds[1:] + ds[:-1]) * np.diff(tau))])
    s_grid = np.linspace(0.0, s[-1], _LEMNISCATE_TABLE_SIZE + 1)
    tau_grid = np.interp(s_grid, s, tau)
    return tau_grid, np.sqrt(1.0 + np.sin(tau_grid) ** 2), float(s[-1])


def _arc_length(params: TrajectoryParams, t: jnp.ndarray) -> jnp.ndarray:
    """Distance travelled along the path at time t (m): linear speed ramp, then constant speed."""
    ramp = params.ramp_time
    safe_ramp = jnp.maximum(ramp, 1e-6)  # keeps the unused branch finite when ramp = 0
    tc = jnp.where(t < 0, 0.0, t)  # not maximum: its derivative at t = 0 would be 1/2
    return params.speed * jnp.where(tc < ramp, tc * tc / (2 * safe_ramp), tc - 0.5 * ramp)


def _position(kind: str, params: TrajectoryParams, t: jnp.ndarray) -> jnp.ndarray:
    return point_at(kind, params, _arc_length(params, t))


def point_at(kind: str, params: TrajectoryParams, s: jnp.ndarray) -> jnp.ndarray:
    """The point (..., 3) m, world frame, at arc length s (m) from the path's start point (any s:
    closed figures repeat, the helix continues); `speed` and `ramp_time` play no part."""
    r = params.size
    zero = jnp.zeros_like(s)
    if kind == "circle":
        theta = 2 * jnp.pi * params.phase + params.direction * s / r
        local = (r * jnp.cos(theta), r * jnp.sin(theta), zero)
    elif kind == "helix":
        lap = 2 * jnp.pi * r
        s_h = s * lap / jnp.sqrt(lap * lap + params.pitch**2)  # horizontal share of the arc length
        theta = 2 * jnp.pi * params.phase + params.direction * s_h / r
        local = (r * jnp.cos(theta), r * jnp.sin(theta), -params.pitch * s_h / lap)
    else:
        table, slope, unit_length = _lemniscate_table()
        n = table.shape[0] - 1
        u = jnp.mod(params.phase + params.direction * s / (r * unit_length), 1.0) * n
        i = jnp.clip(jnp.floor(u), 0, n - 1)
        f = u - i
        k = i.astype(jnp.int32)
        # cubic Hermite in s with the exact dτ/ds at the nodes (C1, speed ripple ~1e-7 in float64);
        # written with the float64 increments Δτ so float32 derivatives avoid cancellation
        tau_tab = jnp.asarray(table, s.dtype)
        rise = jnp.asarray(np.diff(table), s.dtype)
        step = jnp.asarray(slope * (unit_length / n), s.dtype)
        f2, f3 = f * f, f * f * f
        tau = tau_tab[k] + (3 * f2 - 2 * f3) * rise[k] + (f3 - 2 * f2 + f) * step[k] + (f3 - f2) * step[k + 1]
        sin, cos = jnp.sin(tau), jnp.cos(tau)
        den = 1.0 + sin * sin
        local = (r * cos / den, r * sin * cos / den, zero)
    ch, sh = jnp.cos(params.heading), jnp.sin(params.heading)
    x, y, z = local
    offset = jnp.stack([ch * x - sh * y, sh * x + ch * y, z], axis=-1)
    return params.center + offset


def reference(kind: str, params: TrajectoryParams, t: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Reference (position (..., 3) m, velocity (..., 3) m/s), world frame, at t (() or (k,)) s.

    t counts from the episode start; times before 0 hold the start point. The velocity is the exact
    derivative of the position with respect to t.
    """
    _check_kind(kind)
    t = jnp.asarray(t, jnp.result_type(float))
    return jax.jvp(lambda tt: _position(kind, params, tt), (t,), (jnp.ones_like(t),))


def path_length(kind: str, params: TrajectoryParams) -> jnp.ndarray:
    """Length of one lap (m); lap time after the ramp = path_length / speed."""
    _check_kind(kind)
    r = params.size
    if kind == "circle":
        return 2 * jnp.pi * r
    if kind == "helix":
        return jnp.sqrt((2 * jnp.pi * r) ** 2 + params.pitch**2)
    return r * _lemniscate_table()[2]
