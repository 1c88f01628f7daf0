"""Ray casting against the scene, for the sensors that see the world (altimeter, sonar).

A sensor is mounted on the vehicle at a point and casts beams, unit directions in the body frame
(FLU); `SceneRays.cast` returns, per beam, the range (m) to the first scene geom it meets within
`max_range`, and whether it met one. It runs inside jit and vmaps over beams and vehicles
(`mujoco.mjx.ray`, one ray per call).

What the rays see: every geom of the scene except those in group 1, which scenes use for what is
drawn only (the open-water seabed, 10 m down in videos, is not a seabed a sensor could range on),
and never the vehicle's own geoms. MJX casts rays on planes, spheres, capsules, ellipsoids, boxes
and meshes; cylinders and height fields are invisible to it, so scenes build what sensors must see
from those shapes. Geoms with a transparent colour are skipped by MJX itself.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from mujoco import mjx

from marinejax.frames import quat_to_mat
from marinejax.physics import VehicleState

# geom groups 0-5 the rays see: all but group 1 (drawn only)
SEEN_GROUPS = (1, 0, 1, 1, 1, 1)


class SceneRays:
    """Ray casts from one vehicle into its scene; the vehicle's bodies are looked up here, once."""

    def __init__(self, mj_model, body_id: int):
        root = mj_model.body_rootid[body_id]
        self.exclude = tuple(int(b) for b in np.nonzero(mj_model.body_rootid == root)[0])
        seen = np.asarray(SEEN_GROUPS, bool)[np.clip(mj_model.geom_group, 0, 5)]
        seen &= ~np.isin(mj_model.geom_bodyid, self.exclude)
        self.num_geoms = int(seen.sum())  # how many geoms a ray is tested against

    def cast(self, model: mjx.Model, data: mjx.Data, vs: VehicleState, mount: jnp.ndarray, directions: jnp.ndarray,
             max_range: float) -> tuple[jnp.ndarray, jnp.ndarray]:
        """Beams from the mount point `mount` (3, m, body) along `directions` (..., 3, unit, body) of a
        vehicle at `vs`, in the scene of `model` and `data` (`Plant.world`). Returns (range (...,) m,
        clipped to `max_range`; hit (...,) bool: a geom within `max_range`)."""
        rot = quat_to_mat(vs.quaternion)
        origin = vs.position + rot @ mount
        flat = directions.reshape(-1, 3) @ rot.T

        def one(vec):
            return mjx.ray(model, data, origin, vec, geomgroup=SEEN_GROUPS, bodyexclude=self.exclude)[0]

        dist = jax.vmap(one)(flat).reshape(directions.shape[:-1])
        hit = (dist >= 0) & (dist <= max_range)
        return jnp.where(hit, dist, max_range), hit


def fan(horizontal: int, horizontal_fov: float, vertical: int, vertical_fov: float, tilt: float) -> np.ndarray:
    """Unit beam directions (horizontal, vertical, 3), body frame FLU, of a fan centred on the x axis
    pitched down by `tilt` (rad): azimuths evenly over `horizontal_fov` (rad, positive to the left),
    elevations evenly over `vertical_fov` (rad). A single beam or row points at the centre."""

    def spread(n, fov):
        return np.zeros(1) if n == 1 else np.linspace(-fov / 2, fov / 2, n)

    az, el = np.meshgrid(spread(horizontal, horizontal_fov), spread(vertical, vertical_fov) - tilt, indexing="ij")
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1).astype(np.float32)
