"""The actuator contract: what a kind of actuator (thruster, propeller, control fin) provides.

A vehicle's MJCF file declares its actuators as groups, in action order, with its custom text
`marinejax:actuators`, e.g. `data="thruster:t200"`: each entry `<prefix>:<kind>` is a group of
sites `<prefix>1..<prefix>N` (position and axis of each actuator, body frame) handled by the
registered kind `<kind>`, with its settings in the custom fields `marinejax:<prefix>:<field>`.

A kind is one module with one `ActuatorKind` subclass registered under its name
(`marinejax.actuators.register_kind`). It owns two pytrees per group:
- `design`: what the vehicle file fixes (geometry, tables), shared by every episode;
- `params`: what may differ per episode (gains, time constants, supply voltage): `PlantParams`
  holds one per group, randomization draws it, identification fits it.
Every actuator has one state in physical units (a thruster's thrust in N, a fin's angle in rad, a
propeller's speed in rev/min), moved towards the target its command sets; the vehicle's actuator
state is the concatenation over groups, in action order. Commands are normalised to [−1, 1].
"""

from __future__ import annotations

from typing import Any, Callable, ClassVar

import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct

from marinejax.errors import UserError

Draw = Callable[[tuple[float, float], tuple[int, ...]], jnp.ndarray]  # uniform draw in a range, of a shape


class ActuatorKind:
    """One kind of actuator. Stateless: every method is a pure function of its arguments."""

    name: ClassVar[str]  # the kind's name in a vehicle file

    def load(self, m: mujoco.MjModel, sites: list[int], settings: dict[str, Any], where: str) -> tuple[Any, Any]:
        """(design, params) of a group from its sites (ids in `m`, in order) and its custom fields
        `settings` (field → float array or text). Raises UserError naming `where`, the field and the
        valid values on a missing or bad setting."""
        raise NotImplementedError

    def target(self, design, params, command: jnp.ndarray) -> jnp.ndarray:
        """(N,) state each actuator settles at under `command` (N,) ∈ [−1, 1]."""
        raise NotImplementedError

    def advance(self, design, params, state: jnp.ndarray, target: jnp.ndarray, dt) -> jnp.ndarray:
        """(N,) state after dt (s) moving from `state` towards `target` (the actuator's own dynamics);
        by default the exact first-order lag of time constant `params.time_constant` (s)."""
        return lag_step(state, target, dt, params.time_constant)

    def wrench(self, design, params, state: jnp.ndarray, nu_r: jnp.ndarray) -> jnp.ndarray:
        """(6,) body wrench [N, N m about the CG], body frame FLU, of the group at `state`, with the
        vehicle moving at `nu_r` (6,) relative to the water (body frame, m/s and rad/s)."""
        raise NotImplementedError

    def describe(self, names: tuple[str, ...], params) -> str:
        """What the commands of a group with sites `names` and nominal `params` mean (units, range,
        sign, order), for exports and documentation."""
        raise NotImplementedError

    def state_range(self, design, params) -> tuple[np.ndarray, np.ndarray]:
        """(states at command −1, states at command +1), each (N,), in the state's unit."""
        raise NotImplementedError

    def randomize(self, params, draw: Draw, config) -> Any:
        """`params` perturbed for one episode within `config` (a RandomizationConfig)."""
        return params

    def privileged(self, params) -> jnp.ndarray:
        """The group's episode parameters as one vector (for an asymmetric critic)."""
        return jnp.zeros(0)

    file_fields: ClassVar[tuple[str, ...]] = ()  # keys of a parameter-set JSON file this kind reads

    def from_file(self, params, values: dict[str, float]) -> Any:
        """`params` with the values of a parameter-set file (keys among `file_fields`) applied."""
        return params

    def check_settings(self, settings: dict[str, Any], known: tuple[str, ...], where: str) -> None:
        """Raise UserError on a setting this kind does not know."""
        unknown = sorted(set(settings) - set(known))
        if unknown:
            raise UserError(f"{where}: unknown setting(s) {unknown} for actuator kind {self.name!r}; valid: {list(known)}")


@struct.dataclass
class ActuatorGroup:
    """A vehicle's actuators of one kind: sites `names` (in action order) with their design and
    nominal episode parameters."""

    kind: ActuatorKind = struct.field(pytree_node=False)
    names: tuple[str, ...] = struct.field(pytree_node=False)
    design: Any
    params: Any

    @property
    def size(self) -> int:
        return len(self.names)


def lag_step(state: jnp.ndarray, target: jnp.ndarray, dt, time_constant: jnp.ndarray) -> jnp.ndarray:
    """Exact first-order lag over dt (s): state → target with time constant τ (s); τ = 0 is instantaneous."""
    alpha = 1.0 - jnp.exp(-dt / jnp.maximum(time_constant, 1e-9))
    return state + alpha * (target - state)


def allocation_matrix(positions: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """6×N matrix B with column i = [e_i; r_i × e_i]; positions r_i (N, 3) m and unit directions e_i (N, 3), body frame."""
    positions = np.asarray(positions, dtype=float)
    directions = np.asarray(directions, dtype=float)
    directions = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    return np.concatenate([directions.T, np.cross(positions, directions).T], axis=0)


def scalar_settings(settings: dict[str, Any], lower: dict[str, float | None], optional: tuple[str, ...], where: str) -> dict[str, float]:
    """The one-number settings named in `lower` (each at least its lower bound, if not None), or a
    UserError naming the setting, its bound and the valid names."""
    out = {}
    for key, low in lower.items():
        if key not in settings:
            raise UserError(f"{where}: missing setting '{key}' (settings: {sorted(lower)}, optional {list(optional)})")
        value = np.asarray(settings[key], float).reshape(-1)
        if value.size != 1 or not np.isfinite(value[0]) or (low is not None and value[0] < low):
            bound = "" if low is None else f" >= {low}"
            raise UserError(f"{where}: setting '{key}' must be one finite number{bound}, got {value.tolist()}")
        out[key] = float(value[0])
    return out


def flow_points(settings: dict[str, Any], positions: np.ndarray, where: str) -> np.ndarray:
    """(N, 3) m, body FLU from the CG: where each actuator takes the water velocity, the setting
    `flow_point` (3 numbers, one point for the group) or, without it, each site's own position."""
    if "flow_point" not in settings:
        return positions
    flow = np.asarray(settings["flow_point"], float).reshape(-1)
    if flow.size != 3 or not np.all(np.isfinite(flow)):
        raise UserError(f"{where}: setting 'flow_point' must be 3 finite numbers (m, body FLU from the CG), got {flow.tolist()}")
    return np.broadcast_to(flow, positions.shape)


def body_wrench(positions: jnp.ndarray, forces: jnp.ndarray, moments: jnp.ndarray | None = None) -> jnp.ndarray:
    """(6,) wrench about the CG of forces (N, 3) acting at positions (N, 3) plus pure moments (N, 3)."""
    moment = jnp.cross(positions, forces) if moments is None else jnp.cross(positions, forces) + moments
    return jnp.concatenate([jnp.sum(forces, axis=0), jnp.sum(moment, axis=0)])


def site_frames(m: mujoco.MjModel, sites: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) m and rotation matrices (N, 3, 3) site → body of `sites`, body frame FLU."""
    positions = np.array([m.site_pos[i] for i in sites], dtype=float)
    mats = []
    for i in sites:
        mat = np.zeros(9)
        mujoco.mju_quat2Mat(mat, m.site_quat[i])
        mats.append(mat.reshape(3, 3))
    return positions, np.array(mats)
