"""Frames and rotations.

marinejax uses MuJoCo's conventions everywhere:
- world frame: x east, y north, z UP (ENU-like; gravity along -z);
- body frame: FLU (x forward, y left/port, z up), origin at the centre of gravity;
- quaternions are scalar-first (w, x, y, z) and rotate body vectors into the world frame.

Published marine data (Fossen/SNAME) use body FRD (x forward, y starboard, z down) and world NED.
`FRD_TO_FLU` converts vectors between the two body frames; it is the only place where that happens.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

# diag(1, -1, -1): maps an FRD body vector to FLU (and back: it is its own inverse).
FRD_TO_FLU = np.diag([1.0, -1.0, -1.0])


def frd_to_flu(v: np.ndarray) -> np.ndarray:
    """Convert a 3-vector (or rows of 3-vectors) from body FRD to body FLU."""
    return np.asarray(v, dtype=float) @ FRD_TO_FLU.T


def quat_to_mat(q: jnp.ndarray) -> jnp.ndarray:
    """Rotation matrix (3, 3) of a unit quaternion (w, x, y, z); maps body vectors to world."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    r = jnp.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        axis=-1,
    )
    return r.reshape(q.shape[:-1] + (3, 3))


def quat_from_euler(roll: float, pitch: float, yaw: float) -> jnp.ndarray:
    """Quaternion (w, x, y, z) from ZYX Euler angles in radians (yaw about world z-up, then pitch, then roll)."""
    cr, sr = jnp.cos(roll / 2), jnp.sin(roll / 2)
    cp, sp = jnp.cos(pitch / 2), jnp.sin(pitch / 2)
    cy, sy = jnp.cos(yaw / 2), jnp.sin(yaw / 2)
    return jnp.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        axis=-1,
    )


def quat_to_euler(q: jnp.ndarray) -> jnp.ndarray:
    """ZYX Euler angles (roll, pitch, yaw) in radians of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    roll = jnp.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = jnp.arcsin(jnp.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = jnp.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return jnp.stack([roll, pitch, yaw], axis=-1)


def quat_multiply(p: jnp.ndarray, q: jnp.ndarray) -> jnp.ndarray:
    """Hamilton product p ⊗ q of quaternions (w, x, y, z)."""
    pw, pv, qw, qv = p[..., :1], p[..., 1:], q[..., :1], q[..., 1:]
    w = pw * qw - jnp.sum(pv * qv, axis=-1, keepdims=True)
    return jnp.concatenate([w, pw * qv + qw * pv + jnp.cross(pv, qv)], axis=-1)


def quat_integrate(q: jnp.ndarray, omega_body: jnp.ndarray, dt) -> jnp.ndarray:
    """Rotate unit quaternion q (body → world) by a constant body-frame angular velocity ω (rad/s)
    held for dt (s): q ⊗ exp(ω dt / 2), exact for constant ω, renormalised; differentiable at ω = 0."""
    half = 0.5 * dt * omega_body
    th2 = jnp.sum(half * half, axis=-1, keepdims=True)
    small = th2 < 1e-8
    th = jnp.sqrt(jnp.where(small, 1.0, th2))
    sinc = jnp.where(small, 1.0 - th2 / 6.0, jnp.sin(th) / th)
    cos = jnp.where(small, 1.0 - th2 / 2.0, jnp.cos(th))
    out = quat_multiply(q, jnp.concatenate([cos, sinc * half], axis=-1))
    return out / jnp.linalg.norm(out, axis=-1, keepdims=True)


def quat_angle_between(q1: jnp.ndarray, q2: jnp.ndarray) -> jnp.ndarray:
    """Smallest rotation angle (rad) between two unit quaternions."""
    d = jnp.abs(jnp.sum(q1 * q2, axis=-1))
    return 2 * jnp.arccos(jnp.clip(d, 0.0, 1.0))
