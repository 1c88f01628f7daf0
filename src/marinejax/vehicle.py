"""Vehicles: an MJCF model plus its hydrodynamic parameters and its actuators, loaded once, placed
in a scene (`marinejax.scene`).

A vehicle is one MJCF file in `models/mjcf/` (installed as `marinejax/models/mjcf/`): one body
with a free joint, its cameras, visual geoms (class "visual", no contacts) and collision geoms
(class "collision", simple shapes, used only in scenes with contacts). Its `<custom>` section
carries named parameter sets (`marinejax:<set>:<field>`) and declares its actuators
(`marinejax:actuators`, see `marinejax.actuators`), whose sites give each actuator's position and
axis. Adding a vehicle means adding one file; no code change.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct
from mujoco import mjx

from marinejax.errors import MissingFileError, UserError
from marinejax.actuators import ActuatorGroup, custom_text, declared_groups, load_actuators
from marinejax.actuators.base import site_frames
from marinejax.hydro.forces import added_mass_at_cg
from marinejax.hydro.params import FIELDS as HYDRO_FIELDS, HydroParams
from marinejax.model_files import models_dir
from marinejax.scene import DEFAULT_SCENE, compose, contacts_enabled

_PREFIX = "marinejax:"
_RIGID_FIELDS = {"mass": 1, "inertia": 3}



def mjx_device() -> jax.Device:
    """The device MJX models and data are placed on: this process's first local device. (MJX's
    default is `jax.devices()[0]`, which belongs to process 0 when several processes train together.)"""
    return jax.local_devices()[0]


def model_dir() -> Path:
    """Folder holding the vehicle MJCF files: the installed package copy, else the source checkout's."""
    return models_dir("mjcf")


def list_vehicles() -> list[str]:
    """Names of the available vehicles (MJCF file stems), computed when asked."""
    return sorted(p.stem for p in model_dir().glob("*.xml"))


@functools.lru_cache(maxsize=64)
def _custom(path: str, mtime_ns: int) -> tuple[dict[str, str], dict[str, list[float] | str]]:
    """(texts, numerics) of an MJCF file's <custom> section, by name; parsed once per file version."""
    import xml.etree.ElementTree as ElementTree

    root = ElementTree.parse(path).getroot()
    texts = {t.get("name", ""): t.get("data", "") for t in root.iter("text")}
    numerics = {}
    for n in root.iter("numeric"):
        try:
            numerics[n.get("name", "")] = [float(v) for v in n.get("data", "").split()]
        except ValueError:
            numerics[n.get("name", "")] = n.get("data", "")  # reported by whoever reads it
    return texts, numerics


def _custom_of(vehicle: str) -> tuple[dict[str, str], dict[str, list[float] | str]]:
    path = model_dir() / f"{vehicle}.xml"
    return _custom(str(path), path.stat().st_mtime_ns)


def env_name_prefix(vehicle: str) -> str:
    """The prefix of vehicle `vehicle`'s env names (`<prefix>-<Task>`): the MJCF's custom text
    `marinejax:env_name`, else the file stem in CamelCase (my_rov → MyRov). Reads the XML only."""
    name = _custom_of(vehicle)[0].get(_PREFIX + "env_name")
    return name or "".join(part[:1].upper() + part[1:] for part in vehicle.split("_"))


VEHICLE_KINDS = ("rov", "torpedo")  # rov: hovers on thrusters; torpedo: one propeller and fins, cannot hover


def vehicle_kind(vehicle: str) -> str:
    """What kind of vehicle `vehicle` is (which tasks it can do): the MJCF's custom text
    `marinejax:vehicle_kind`, one of VEHICLE_KINDS, "rov" if absent. Reads the XML only."""
    kind = _custom_of(vehicle)[0].get(_PREFIX + "vehicle_kind", "rov")
    if kind not in VEHICLE_KINDS:
        raise UserError(f"vehicle {vehicle!r} ({vehicle}.xml): unknown vehicle kind {kind!r}; valid: {list(VEHICLE_KINDS)}")
    return kind


def sensor_settings(vehicle: str) -> dict[str, float]:
    """The vehicle's own sensor parameters: the MJCF's numerics `marinejax:sensors:<sensor>.<field>`
    (e.g. `marinejax:sensors:dvl.rate_hz`, `marinejax:sensors:sonar.position` with three numbers),
    as overrides of the env config's `sensors` section, whose defaults (`marinejax.plant.sensors`)
    are a BlueROV2's. Reads the XML only."""
    prefix = _PREFIX + "sensors:"
    out = {}
    for name, values in _custom_of(vehicle)[1].items():
        if name.startswith(prefix):
            if isinstance(values, str) or not values:
                raise UserError(f"vehicle {vehicle!r} ({vehicle}.xml): '{name}' must hold numbers, got {values!r}")
            out[name[len(prefix):]] = values[0] if len(values) == 1 else tuple(values)
    return out


@struct.dataclass
class VehicleSystem:
    """Everything the jitted physics reads: the MJX model (rigid body, scene, gravity, timestep),
    the fluid parameters and the actuator groups (in action order). Indices are static Python ints,
    looked up once at load; `contacts` says whether the scene collides (the physics then puts the
    added mass into MuJoCo's mass matrix, `marinejax.physics`)."""

    model: mjx.Model
    hydro: HydroParams
    actuators: tuple[ActuatorGroup, ...]
    body_id: int = struct.field(pytree_node=False)
    qpos_adr: int = struct.field(pytree_node=False)
    dof_adr: int = struct.field(pytree_node=False)
    contacts: bool = struct.field(pytree_node=False, default=False)
    layout_ids: tuple[int, ...] = struct.field(pytree_node=False, default=())  # scene geoms placed per episode (`PlantParams.layout`)

    @property
    def num_actuators(self) -> int:
        return sum(g.size for g in self.actuators)


@dataclasses.dataclass(frozen=True, eq=False)
class Vehicle:
    """A loaded vehicle: `sys` for jitted code, the CPU `mj_model` for rendering, and metadata."""

    name: str
    param_set: str
    param_sets: tuple[str, ...]
    source: str  # citation of the parameter set
    mj_model: mujoco.MjModel  # the vehicle in its scene, compiled (rendering draws it)
    sys: VehicleSystem
    actuator_names: tuple[str, ...]  # sites of the actuators, in action order
    path: Path  # the vehicle's MJCF file
    scene: str = DEFAULT_SCENE  # the scene's name (or file path)

    @property
    def num_actuators(self) -> int:
        return len(self.actuator_names)

    def describe_action(self) -> str:
        """What each component of the action means (units, signs, order), from the actuator kinds."""
        return "; then ".join(g.kind.describe(g.names, g.params) for g in self.sys.actuators)

    def action_mirror(self) -> tuple[np.ndarray, np.ndarray]:
        """(perm, sign): the mirror image of actuator commands `a` under the reflection y → −y of the
        body frame is `sign * a[perm]`. Actuator i's image is the actuator of its kind at its reflected
        site whose axis (site z: where a positive command pushes or lifts) is the reflected axis
        (sign +1) or its opposite (−1). Exact for fins and propellers, except the propeller's torque
        (a mirrored propeller turns the other way); a T200 mapped with sign −1 pushes less in reverse
        than forward. Raises UserError naming an actuator without an image."""
        m = self.mj_model
        kinds = [g.kind.name for g in self.sys.actuators for _ in range(g.size)]
        sites = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name) for name in self.actuator_names]
        positions, rotations = site_frames(m, sites)
        axes = rotations[:, :, 2]
        reflect = np.array([1.0, -1.0, 1.0])
        perm, sign = np.zeros(len(sites), int), np.zeros(len(sites), np.float32)
        for i in range(len(sites)):
            for j in range(len(sites)):
                if kinds[j] == kinds[i] and np.allclose(positions[j], reflect * positions[i], atol=1e-4):
                    dot = float(axes[j] @ (reflect * axes[i]))
                    if abs(abs(dot) - 1.0) < 1e-4:
                        perm[i], sign[i] = j, np.sign(dot)
                        break
            else:
                raise UserError(f"{self.name}: actuator {self.actuator_names[i]!r} has no mirror image (an actuator of kind "
                                f"{kinds[i]!r} at its site reflected through the x-z plane, with the reflected axis)")
        return perm, sign


def _numerics(m: mujoco.MjModel, prefix: str) -> dict[str, np.ndarray]:
    out = {}
    for i in range(m.nnumeric):
        name = m.numeric(i).name
        if name.startswith(prefix):
            out[name[len(prefix) :]] = np.array(m.numeric(i).data, dtype=np.float64)
    return out


def _param_sets(m: mujoco.MjModel, where: str) -> list[str]:
    not_sets = {prefix for prefix, _ in declared_groups(m, where)} | {"sensors"}
    sets = set()
    for i in range(m.nnumeric):
        parts = m.numeric(i).name.split(":")
        if len(parts) == 3 and parts[0] + ":" == _PREFIX and parts[1] not in not_sets:
            sets.add(parts[1])
    return sorted(sets)


_FILE_FIELDS = (*HYDRO_FIELDS, *_RIGID_FIELDS)


def _read_param_file(path: Path, vehicle: str, actuator_fields: tuple[str, ...]) -> tuple[dict[str, np.ndarray], dict[str, float], str]:
    """A parameter-set JSON file: {vehicle, source, <fields of a set>, <the actuator kinds' file
    fields, e.g. thruster_gain, thruster_time_constant>}."""
    import json

    if not path.is_file():
        raise MissingFileError(f"parameter-set file not found: {path}")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise UserError(f"{path}: not valid JSON ({err})") from None
    if data.get("vehicle") not in (None, vehicle):
        raise UserError(f"{path} holds parameters of vehicle {data.get('vehicle')!r}, not {vehicle!r}")
    values = {k: np.atleast_1d(np.asarray(data[k], dtype=np.float64)) for k in _FILE_FIELDS if k in data}
    actuators = {k: float(data[k]) for k in actuator_fields if k in data}
    for k, v in actuators.items():
        if not (np.isfinite(v) and v >= 0):
            raise UserError(f"{path}: '{k}' must be finite and >= 0, got {v}")
    return values, actuators, data.get("source", str(path))


def load_vehicle(name: str | Path, param_set: str | None = None, scene: str | Path = DEFAULT_SCENE) -> Vehicle:
    """Load a vehicle by name (see `list_vehicles()`) or from an MJCF file path ending in .xml,
    with its default or a named parameter set, or a parameter-set .json file (fields of a set plus
    its actuators' file fields, e.g. thruster_gain and thruster_time_constant; `marinejax identify`
    writes one), placed in `scene` (a name of `marinejax.scene.list_scenes()` or an MJCF path).

    Raises UserError (a ValueError) naming the bad value and the valid choices for an unknown vehicle,
    scene or parameter set, and for missing, non-finite or unphysical parameters.
    """
    if str(name).endswith(".xml"):
        path = Path(name)
        if not path.is_file():
            raise MissingFileError(f"vehicle model file not found: {path}")
        name = path.stem
    else:
        names = list_vehicles()
        if name not in names:
            raise UserError(f"unknown vehicle {name!r}; available vehicles: {names}")
        path = model_dir() / f"{name}.xml"
    where = f"vehicle {name!r} ({path.name})"
    spec = mujoco.MjSpec.from_file(str(path))
    own = [b for b in spec.worldbody.bodies]
    if len(own) != 1 or own[0].bodies or len(own[0].joints) != 1 or own[0].joints[0].type != mujoco.mjtJoint.mjJNT_FREE:
        raise UserError(f"{where}: expected exactly one body with one free joint")
    m = compose(spec, scene).compile()
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, own[0].name)
    actuators = load_actuators(m, body, where)
    sets = _param_sets(m, where)
    default = custom_text(m, _PREFIX + "default_set")
    param_set = param_set or default
    file_values, actuator_file = {}, {}
    source = None
    if str(param_set).endswith(".json"):  # a parameter-set file, e.g. written by `marinejax identify`
        fields = tuple(f for g in actuators for f in g.kind.file_fields)
        file_values, actuator_file, source = _read_param_file(Path(param_set), name, fields)
        actuators = tuple(g.replace(params=g.kind.from_file(g.params, actuator_file)) for g in actuators)
        values = {**_numerics(m, f"{_PREFIX}{default}:"), **file_values}
    elif param_set not in sets:
        raise UserError(f"{where}: unknown parameter set {param_set!r}; available: {sets} or a parameter-set .json file")
    else:
        values = _numerics(m, f"{_PREFIX}{param_set}:")
    rigid = {k: values.pop(k) for k in list(values) if k in _RIGID_FIELDS}
    hydro = HydroParams.from_mapping(values, source=f"{where}, parameter set {param_set!r}")

    if not (np.allclose(m.body_ipos[body], 0) and np.allclose(m.body_iquat[body], [1, 0, 0, 0])):
        raise UserError(f"{where}: the body frame origin must be the centre of gravity with principal axes "
                         f"(inertial pos 0 0 0, no rotation); got ipos {m.body_ipos[body]}, iquat {m.body_iquat[body]}")
    if not np.allclose(m.opt.gravity[:2], 0) or m.opt.gravity[2] >= 0:
        raise UserError(f"{where}: gravity must point along world -z, got {m.opt.gravity}")
    for field, size in _RIGID_FIELDS.items():
        if field in rigid:
            v = rigid[field]
            if v.size != size or not np.all(np.isfinite(v)) or np.any(v <= 0):
                raise UserError(f"{where}, parameter set {param_set!r}: '{field}' must be {size} finite positive value(s), got {v.tolist()}")
    if "mass" in rigid:
        m.body_mass[body] = rigid["mass"][0]
    if "inertia" in rigid:
        m.body_inertia[body] = rigid["inertia"]
    total = np.diag(np.concatenate([np.full(3, m.body_mass[body]), m.body_inertia[body]])) + np.asarray(added_mass_at_cg(hydro), float)
    if np.linalg.eigvalsh(total).min() <= 0:
        raise UserError(f"{where}, parameter set {param_set!r}: rigid-body plus added mass must be positive definite; "
                        f"its eigenvalues are {np.round(np.linalg.eigvalsh(total), 4).tolist()}")

    _set_inverse_weights(m, body, total)
    contacts = contacts_enabled(m)
    if contacts and mjx.is_sparse(m):
        raise UserError(f"{where} in scene {scene!r}: MuJoCo chose a sparse mass matrix ({m.nv} degrees of freedom); "
                        "contacts need the dense one: set <option jacobian=\"dense\"/>")
    sys = VehicleSystem(
        model=mjx.put_model(m, device=mjx_device()),
        hydro=hydro,
        actuators=actuators,
        body_id=body,
        qpos_adr=int(m.jnt_qposadr[m.body_jntadr[body]]),
        dof_adr=int(m.jnt_dofadr[m.body_jntadr[body]]),
        contacts=contacts,
    )
    return Vehicle(
        name=name,
        param_set=param_set,
        param_sets=tuple(sets),
        source=source or custom_text(m, f"{_PREFIX}{param_set}:source") or "",
        mj_model=m,
        sys=sys,
        actuator_names=tuple(n for g in actuators for n in g.names),
        path=Path(path),
        scene=str(scene),
    )


def _set_inverse_weights(m: mujoco.MjModel, body: int, mass_matrix: np.ndarray) -> None:
    """MuJoCo's contact softness is scaled by each body's inverse weight (`body_invweight0`,
    `dof_invweight0`: mean diagonal of the inverse inertia, translation and rotation), computed by the
    compiler from the rigid body alone; set them from the rigid-plus-added `mass_matrix` (6, 6, body
    frame at the CG) so that a contact acts on the inertia the fluid gives the vehicle."""
    inverse = np.linalg.inv(mass_matrix)
    translation, rotation = np.trace(inverse[:3, :3]) / 3, np.trace(inverse[3:, 3:]) / 3
    m.body_invweight0[body] = [translation, rotation]
    dof = m.jnt_dofadr[m.body_jntadr[body]]
    m.dof_invweight0[dof : dof + 6] = [translation] * 3 + [rotation] * 3


@struct.dataclass
class Capsules:
    a: jnp.ndarray  # (k, 3) m, body: one end of each capsule's axis
    b: jnp.ndarray  # (k, 3) m, body: the other
    radius: jnp.ndarray  # (k,) m


def collision_capsules(m, body_id: int, vehicle: str) -> Capsules:
    """The vehicle's collision geoms (on its body `body_id` of MuJoCo model `m`, colliding) as capsule
    axes in the body frame, for tasks that measure a clearance themselves; a sphere is a capsule of
    zero length. UserError naming the geom for another shape."""
    a, b, radius = [], [], []
    for i in np.nonzero((m.geom_bodyid == body_id) & (m.geom_contype != 0))[0]:
        kind = int(m.geom_type[i])
        if kind not in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_SPHERE)):
            raise UserError(f"vehicle {vehicle!r}: clearances are measured to capsule or sphere collision geoms, "
                            f"geom {m.geom(i).name!r} is a {mujoco.mjtGeom(kind).name}")
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, m.geom_quat[i])
        half = rot.reshape(3, 3)[:, 2] * (m.geom_size[i, 1] if kind == int(mujoco.mjtGeom.mjGEOM_CAPSULE) else 0.0)
        centre = m.geom_pos[i]  # body frame, about the body's origin (VehicleState.position)
        a.append(centre - half)
        b.append(centre + half)
        radius.append(m.geom_size[i, 0])
    if not radius:
        raise UserError(f"vehicle {vehicle!r} has no collision geoms (class \"collision\" in its MJCF)")
    return Capsules(a=jnp.asarray(np.array(a), jnp.float32), b=jnp.asarray(np.array(b), jnp.float32),
                    radius=jnp.asarray(np.array(radius), jnp.float32))
