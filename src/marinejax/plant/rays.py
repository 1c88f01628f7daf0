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

Speed: a scene's geoms are static (a scene has no joints) except the ones a task moves per episode
(`PlantParams.layout`). So the rays are cast into a model of the seen geoms alone, at their world
poses, computed once here: MJX then tests each ray against those geoms only, and no forward
kinematics runs per step. Scenes with meshes keep the full model (the mesh data lives there).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from marinejax.config import check_fields
from marinejax.errors import UserError
from marinejax.frames import quat_to_mat
from marinejax.physics import VehicleState
from marinejax.vehicle import mjx_device

# geom groups 0-5 the rays see: all but group 1 (drawn only)
SEEN_GROUPS = (1, 0, 1, 1, 1, 1)
_PRIMITIVES = {int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CAPSULE),
               int(mujoco.mjtGeom.mjGEOM_ELLIPSOID), int(mujoco.mjtGeom.mjGEOM_BOX)}


class SceneRays:
    """Ray casts from one vehicle into its scene. `mj_model`: the vehicle in its scene; `body_id`:
    the vehicle's body; `layout_ids`: the scene geoms placed per episode (`PlantParams.layout`)."""

    def __init__(self, mj_model: mujoco.MjModel, body_id: int, layout_ids: tuple[int, ...] = ()):
        root = mj_model.body_rootid[body_id]
        vehicle = np.isin(mj_model.geom_bodyid, np.nonzero(mj_model.body_rootid == root)[0])
        seen = np.asarray(SEEN_GROUPS, bool)[np.clip(mj_model.geom_group, 0, 5)] & ~vehicle
        seen &= mj_model.geom_rgba[:, 3] != 0  # MJX skips transparent geoms
        seen &= np.isin(mj_model.geom_type, list(_PRIMITIVES | {int(mujoco.mjtGeom.mjGEOM_MESH)}))
        ids = np.nonzero(seen)[0]
        self.num_geoms = int(ids.size)  # how many geoms a ray is tested against
        self.meshes = False  # whether the seen geoms include meshes (no incidence angle then)
        data = mujoco.MjData(mj_model)
        mujoco.mj_kinematics(mj_model, data)  # static geoms' world poses (the vehicle's do not matter)
        if not ids.size:
            self._model = None
        elif np.all(np.isin(mj_model.geom_type[ids], list(_PRIMITIVES))):
            spec = mujoco.MjSpec()
            spec.add_material(name="seen")  # MJX's ray indexes the material colours even for geoms without one
            for i in ids:
                quat = np.zeros(4)
                mujoco.mju_mat2Quat(quat, data.geom_xmat[i])
                spec.worldbody.add_geom(type=mujoco.mjtGeom(int(mj_model.geom_type[i])), size=mj_model.geom_size[i],
                                        pos=data.geom_xpos[i], quat=quat, contype=0, conaffinity=0)
            lean = spec.compile()
            self._model = mjx.put_model(lean, device=mjx_device())
            self._data = mjx.make_data(lean, device=mjx_device()).replace(geom_xpos=jnp.asarray(lean.geom_pos, jnp.float32),
                                                     geom_xmat=jnp.asarray(data.geom_xmat[ids].reshape(-1, 3, 3), jnp.float32))
            self._types = np.asarray(lean.geom_type)  # per lean geom, for the surface normals (incidence)
            self._sizes = jnp.asarray(lean.geom_size, jnp.float32)
            index = {int(g): k for k, g in enumerate(ids)}
            self._layout = [(index[g], k) for k, g in enumerate(layout_ids) if g in index]  # (lean geom, layout row)
            self._full = False
        else:  # meshes: cast into the full model, its poses by kinematics at each call
            self._model, self._full = mjx.put_model(mj_model, device=mjx_device()), True
            self.meshes = True
            self._exclude = tuple(int(b) for b in np.nonzero(mj_model.body_rootid == root)[0])
            self._layout_ids = tuple(layout_ids)

    def _scene(self, layout: jnp.ndarray, data: mjx.Data | None):
        if self._full:
            model = self._model
            if self._layout_ids:
                model = model.replace(geom_pos=jnp.asarray(model.geom_pos).at[np.asarray(self._layout_ids)].set(layout))
            return model, mjx.kinematics(model, data), dict(geomgroup=SEEN_GROUPS, bodyexclude=self._exclude)
        d = self._data
        if self._layout:  # movable geoms are on the world body: their world position is the layout's
            lean, rows = (np.asarray(x) for x in zip(*self._layout))
            d = d.replace(geom_xpos=d.geom_xpos.at[lean].set(layout[rows]))
        return self._model, d, {}

    def cast(self, layout: jnp.ndarray, data: mjx.Data, vs: VehicleState, mount: jnp.ndarray, directions: jnp.ndarray,
             max_range: float, incidence: bool = False):
        """Beams from the mount point `mount` (3, m, body) along `directions` (..., 3, unit, body) of a
        vehicle at `vs`, in the scene with this episode's `layout` (`PlantParams.layout`); `data`: the
        plant's MJX data (read only for scenes with meshes). Returns (range (...,) m, clipped to
        `max_range`; hit (...,) bool: a geom within `max_range`), and with `incidence` a third array
        (...,): the cosine of the angle between each beam and the normal of the surface it hit (1:
        head on; 0 where nothing was hit). Incidence needs primitive geoms (no meshes)."""
        shape = directions.shape[:-1]
        if self._model is None:
            miss = (jnp.full(shape, max_range, jnp.float32), jnp.zeros(shape, bool))
            return (*miss, jnp.zeros(shape, jnp.float32)) if incidence else miss
        if incidence and self._full:
            raise UserError("the incidence angle of a ray needs a scene of primitive geoms (planes, spheres, capsules, "
                            "ellipsoids, boxes); this scene's seen geoms include meshes")
        model, scene, options = self._scene(layout, data)
        rot = quat_to_mat(vs.quaternion)
        origin = vs.position + rot @ mount
        flat = directions.reshape(-1, 3) @ rot.T

        def one(vec):
            return mjx.ray(model, scene, origin, vec, **options)

        dist, geom = jax.vmap(one)(flat)
        hit = (dist >= 0) & (dist <= max_range)
        out = (jnp.where(hit, dist, max_range).reshape(shape), hit.reshape(shape))
        if not incidence:
            return out
        normal = self._normal(scene, jnp.maximum(geom, 0), origin + flat * dist[:, None])
        cos = jnp.where(hit, jnp.abs(jnp.sum(normal * flat, axis=-1)), 0.0)
        return (*out, cos.reshape(shape))

    def _normal(self, scene: mjx.Data, geom: jnp.ndarray, point: jnp.ndarray) -> jnp.ndarray:
        """Unit outward normals (n, 3, world) of the lean model's geoms `geom` (n,) at world points
        `point` (n, 3) on their surfaces."""
        centre, rot = scene.geom_xpos[geom], scene.geom_xmat[geom]
        local = jnp.einsum("nji,nj->ni", rot, point - centre)  # the point in the geom's frame
        size = self._sizes[geom]
        kind = jnp.asarray(self._types)[geom]
        g = mujoco.mjtGeom
        # a capsule's half-length is size[1]: its normal points away from the nearest point of its axis
        axis_point = jnp.zeros_like(local).at[:, 2].set(jnp.clip(local[:, 2], -size[:, 1], size[:, 1]))
        # a box's face: the axis along which the point lies farthest out relative to the half-size
        face = jnp.argmax(jnp.abs(local) / jnp.maximum(size, 1e-9), axis=-1)
        box = jax.nn.one_hot(face, 3) * jnp.sign(jnp.take_along_axis(local, face[:, None], axis=-1))
        n_local = jnp.select(
            [kind[:, None] == int(g.mjGEOM_PLANE), kind[:, None] == int(g.mjGEOM_SPHERE), kind[:, None] == int(g.mjGEOM_CAPSULE),
             kind[:, None] == int(g.mjGEOM_ELLIPSOID)],
            [jnp.broadcast_to(jnp.array([0.0, 0.0, 1.0]), local.shape), local, local - axis_point, local / jnp.maximum(size, 1e-9) ** 2],
            box)
        n = jnp.einsum("nij,nj->ni", rot, n_local)
        return n / jnp.maximum(jnp.linalg.norm(n, axis=-1, keepdims=True), 1e-9)


def fan(horizontal: int, horizontal_fov: float, vertical: int, vertical_fov: float, tilt: float) -> np.ndarray:
    """Unit beam directions (horizontal, vertical, 3), body frame FLU, of a fan centred on the x axis
    pitched down by `tilt` (rad): azimuths evenly over `horizontal_fov` (rad, positive to the left),
    elevations evenly over `vertical_fov` (rad). A single beam or row points at the centre."""
    az, el = np.meshgrid(spread(horizontal, horizontal_fov), spread(vertical, vertical_fov) - tilt, indexing="ij")
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1).astype(np.float32)


def spread(n: int, fov: float) -> np.ndarray:
    """n angles (rad) evenly over `fov` centred on zero, from −fov/2; one angle: zero."""
    return np.zeros(1) if n == 1 else np.linspace(-fov / 2, fov / 2, n)


def check_ray_sensor(section: str, config, counts: tuple[str, ...] = ("beams",)) -> None:
    """Validate a ray-cast sensor's config (`section`: its dotted key): every number finite and
    >= 0, the ray `counts` >= 1, min_range < max_range, rate_hz > 0, dropout < 1, a 3-number mount
    `position`; UserError naming the values otherwise."""
    check_fields(section, config)
    values = {n: getattr(config, n) for n in (*counts, "min_range", "max_range", "rate_hz", "dropout")}
    if (any(values[n] < 1 for n in counts) or not config.min_range < config.max_range or not config.rate_hz > 0
            or not config.dropout < 1):
        raise UserError(f"config '{section}' needs {', '.join(f'{n} >= 1' for n in counts)}, min_range < max_range, "
                        f"rate_hz > 0 and dropout < 1; got {', '.join(f'{k}={v}' for k, v in values.items())}")
    if len(config.position) != 3:
        raise UserError(f"config '{section}.position' must be 3 numbers (m, body FLU), got {config.position!r}")
