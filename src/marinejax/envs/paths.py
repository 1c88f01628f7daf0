"""Paths for path following: waypoint legs, circle, helix and lemniscate, as pure JAX functions of
the arc length.

World frame, z up, SI units (m, rad). A path is drawn per episode (`sample`) and evaluated at any
arc length s (m) from its start point (`point`: position and unit tangent, the tangent the exact
derivative by forward mode). Unlike a tracking reference (`trajectories`), a path has no time in
it: the vehicle's closest point on it is the task's state (`project`).

Kinds:
  lines       `legs` straight legs joined by horizontal circular arcs of radius `fillet_radius` (the
              turn at each waypoint, of `turn` rad either way): a course a vehicle that cannot hover
              can fly without leaving it. Each leg climbs or dives at a grade within ±`leg_grade`
              (dz per m along the leg), the turns are level: the climb angle changes, by up to
              2 atan(leg_grade), where a turn starts and ends. The last leg continues without end,
              the first backwards.
  circle      horizontal, radius `radius`; helix: the same in plan view, descending `helix_pitch`
              m per turn; lemniscate of Bernoulli of half-width `lemniscate_size` (its tightest
              radius of curvature is a third of that). These three are `trajectories`' shapes.
The defaults keep every radius of curvature at or above 25 m, beyond the REMUS 100's turning
circle at full rudder (37 m across at full speed, `marinejax validate --vehicle remus100`; 48 m
across at 1 m/s, the slowest commanded speed).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.config import check_range
import marinejax.envs.trajectories as trajectories
from marinejax.errors import UserError

KINDS = ("lines", "circle", "helix", "lemniscate")


def check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise UserError(f"unknown path kind {kind!r}; valid kinds: {list(KINDS)}")


@dataclasses.dataclass(frozen=True)
class PathConfig:
    """Per-episode path distribution; each (low, high) range is drawn uniformly."""

    speed: tuple[float, float] = (1.0, 2.0)  # m/s: the speed to follow the path at
    depth: tuple[float, float] = (-30.0, -10.0)  # m, world z of the start point
    radius: tuple[float, float] = (25.0, 50.0)  # m: circle and helix
    helix_pitch: tuple[float, float] = (5.0, 15.0)  # m of descent per turn
    lemniscate_size: tuple[float, float] = (75.0, 150.0)  # m, half-width (smallest radius of curvature a/3)
    legs: int = 4  # lines: straight legs
    leg_length: tuple[float, float] = (30.0, 60.0)  # m, straight part of each leg
    turn: tuple[float, float] = (0.5, 2.0)  # rad, size of each turn (its side is drawn)
    leg_grade: float = 0.1  # largest |dz/ds| of a leg
    fillet_radius: float = 25.0  # m, radius of the turns between legs

    def __post_init__(self):
        for name in ("speed", "radius", "lemniscate_size", "leg_length"):
            check_range(f"path.{name}", getattr(self, name), positive=True)
        check_range("path.depth", self.depth)
        check_range("path.helix_pitch", self.helix_pitch)
        check_range("path.turn", self.turn, low=0.0)
        if self.turn[1] > math.pi:
            raise UserError(f"config 'path.turn' must lie within [0, pi] rad, got {self.turn}")
        if self.legs < 1:
            raise UserError(f"config 'path.legs' must be >= 1, got {self.legs}")
        if not (0 <= self.leg_grade < 1):
            raise UserError(f"config 'path.leg_grade' must be in [0, 1), got {self.leg_grade}")
        if not self.fillet_radius > 0:
            raise UserError(f"config 'path.fillet_radius' must be > 0, got {self.fillet_radius}")


@struct.dataclass
class Legs:
    """A `lines` path as pieces in order, straight and arc alternating (P = 2 legs − 1)."""

    start_s: jnp.ndarray  # (P,) m, arc length where each piece starts
    start: jnp.ndarray  # (P, 3) m, world: a straight's first point
    direction: jnp.ndarray  # (P, 3) a straight's unit direction
    center: jnp.ndarray  # (P, 3) m, world: an arc's centre (at its depth)
    angle: jnp.ndarray  # (P,) rad: an arc's start point is center + R (cos, sin, 0)(angle)
    side: jnp.ndarray  # (P,) +1 turns left (counter-clockwise seen from above), −1 right
    radius: jnp.ndarray  # () m


def sample(kind: str, rng: jax.Array, config: PathConfig, turn_scale: jnp.ndarray | float = 1.0,
           grade_scale: jnp.ndarray | float = 1.0):
    """One episode's path of `kind` (static under jit): a `Legs`, or a `trajectories.TrajectoryParams`.
    `turn_scale` (≥ 1, may be traced) multiplies every radius of curvature (the circle's and the
    helix's radius, with the helix's descent per turn, the lemniscate's size, the legs' fillet
    radius) and leaves the start point, the start direction, the grades and the legs' lengths as
    they are; `grade_scale` (≤ 1, may be traced) multiplies the grades (dz per m along the path:
    the legs', the helix's)."""
    check_kind(kind)
    if kind != "lines":
        size = config.lemniscate_size if kind == "lemniscate" else config.radius
        curve = trajectories.TrajectoryConfig(speed=(1.0, 1.0), size=size, helix_pitch=config.helix_pitch,
                                              center_z=config.depth, ramp_time=0.0)
        params = trajectories.sample_params(kind, rng, curve)
        params = params.replace(size=params.size * turn_scale, pitch=params.pitch * turn_scale * grade_scale)
        # place the start point (not the centre) at the origin's x and y, at the drawn depth
        start = trajectories.point_at(kind, params, jnp.zeros(()))
        return params.replace(center=params.center - start.at[2].set(0.0))
    n = config.legs
    k = jax.random.split(rng, 5)
    depth = jax.random.uniform(k[0], minval=config.depth[0], maxval=config.depth[1])
    heading = jax.random.uniform(k[1], minval=-jnp.pi, maxval=jnp.pi)
    lengths = jax.random.uniform(k[2], (n,), minval=config.leg_length[0], maxval=config.leg_length[1])
    grades = jax.random.uniform(k[3], (n,), minval=-config.leg_grade, maxval=config.leg_grade) * grade_scale
    turns = jax.random.uniform(k[4], (max(n - 1, 1), 2))
    turn = (config.turn[0] + turns[:, 0] * (config.turn[1] - config.turn[0])) * jnp.where(turns[:, 1] < 0.5, -1.0, 1.0)
    r = jnp.asarray(config.fillet_radius, jnp.float32) * turn_scale
    point, s = jnp.array([0.0, 0.0, 0.0]).at[2].set(depth), jnp.zeros(())
    pieces = []
    for i in range(n):  # turtle: a straight leg, then the turn towards the next
        gamma = jnp.arctan(grades[i])
        d = jnp.stack([jnp.cos(gamma) * jnp.cos(heading), jnp.cos(gamma) * jnp.sin(heading), jnp.sin(gamma)])
        pieces.append((s, point, d, jnp.zeros(3), jnp.zeros(()), jnp.ones(())))
        point, s = point + lengths[i] * d, s + lengths[i]
        if i == n - 1:
            break
        side = jnp.sign(turn[i])
        center = point + r * side * jnp.stack([-jnp.sin(heading), jnp.cos(heading), 0.0])
        angle = heading - side * jnp.pi / 2
        pieces.append((s, point, jnp.zeros(3), center, angle, side))
        end = angle + turn[i]
        point = center + r * jnp.stack([jnp.cos(end), jnp.sin(end), 0.0])
        s, heading = s + r * jnp.abs(turn[i]), heading + turn[i]
    fields = [jnp.stack(f) for f in zip(*pieces)]
    return Legs(start_s=fields[0], start=fields[1], direction=fields[2], center=fields[3], angle=fields[4], side=fields[5],
                radius=r)


def _legs_point(path: Legs, s: jnp.ndarray) -> jnp.ndarray:
    i = jnp.clip(jnp.sum(s >= path.start_s) - 1, 0, path.start_s.shape[0] - 1)
    u = s - path.start_s[i]
    straight = path.start[i] + u * path.direction[i]
    a = path.angle[i] + path.side[i] * u / path.radius
    arc = path.center[i] + path.radius * jnp.stack([jnp.cos(a), jnp.sin(a), jnp.zeros_like(a)])
    return jnp.where(i % 2 == 1, arc, straight)  # pieces alternate: straight, arc, straight, ...


def point(kind: str, path, s: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """(position (3,) m, unit tangent (3,)), world frame, at arc length s () m."""
    f = _legs_point if kind == "lines" else (lambda p, x: trajectories.point_at(kind, p, x))
    return jax.jvp(lambda x: f(path, x), (s,), (jnp.ones_like(s),))


def project(kind: str, path, s: jnp.ndarray, position: jnp.ndarray, iterations: int = 2) -> jnp.ndarray:
    """The arc length of the point of the path closest to `position` (m, world), searched from s: a
    few steps along the tangent (each exact on a straight, error shrinking by distance / radius of
    curvature on a curve), so the closest point moves continuously and never jumps to another part
    of the path (the lemniscate's crossing)."""
    for _ in range(iterations):
        p, t = point(kind, path, s)
        s = s + jnp.dot(position - p, t)
    return s
