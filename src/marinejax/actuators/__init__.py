"""Actuators as components: the kinds a vehicle file can declare, and the loading of its groups.

Kinds: "t200" (Blue Robotics T200 thruster, `t200.py`), "propeller" (a shaft-driven propeller with
open-water coefficients, `propeller.py`), "fin" (a control fin or pair of fins, `fin.py`). A new
kind is one module with an `ActuatorKind` subclass (contract in `base.py`) and one
`register_kind(...)` call.
"""

from __future__ import annotations

import re

import jax.numpy as jnp
import mujoco
import numpy as np

from marinejax.actuators.base import ActuatorGroup, ActuatorKind, allocation_matrix, lag_step
from marinejax.actuators.fin import Fin
from marinejax.actuators.propeller import Propeller
from marinejax.actuators.t200 import T200
from marinejax.errors import UserError

PREFIX = "marinejax:"
DECLARATION = PREFIX + "actuators"  # custom text: "<site prefix>:<kind> ..." in action order
# The registry of kinds, the one piece of module state here: it only grows (at import, or when a
# user registers a kind of their own).
_KINDS: dict[str, ActuatorKind] = {}


def register_kind(kind: ActuatorKind) -> None:
    """Make actuator kind `kind` available to vehicle files under `kind.name`."""
    if kind.name in _KINDS:
        raise UserError(f"actuator kind {kind.name!r} is already registered")
    _KINDS[kind.name] = kind


def list_kinds() -> list[str]:
    return sorted(_KINDS)


for _kind in (T200(), Propeller(), Fin()):
    register_kind(_kind)


def custom_text(m: mujoco.MjModel, name: str) -> str | None:
    """The MJCF custom text `name` of model `m`, or None."""
    i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TEXT, name)
    if i < 0:
        return None
    adr, size = m.text_adr[i], m.text_size[i]
    return bytes(m.text_data[adr : adr + size - 1]).decode()


def declared_groups(m: mujoco.MjModel, where: str) -> list[tuple[str, str]]:
    """The (site prefix, kind) pairs of the vehicle's `marinejax:actuators` declaration."""
    text = custom_text(m, DECLARATION)
    if not text or not text.split():
        raise UserError(f"{where}: no actuators declared; add <text name=\"{DECLARATION}\" data=\"<site prefix>:<kind> ...\"/> "
                        f"to its <custom> section (kinds: {list_kinds()})")
    groups = []
    for entry in text.split():
        prefix, _, kind = entry.partition(":")
        if not prefix or not re.fullmatch(r"[A-Za-z_]\w*", prefix) or kind not in _KINDS:
            raise UserError(f"{where}: bad actuator entry {entry!r} in {DECLARATION}: expected <site prefix>:<kind> "
                            f"with kind one of {list_kinds()}")
        if prefix in [p for p, _ in groups]:
            raise UserError(f"{where}: actuator site prefix {prefix!r} declared twice in {DECLARATION}")
        groups.append((prefix, kind))
    return groups


def load_actuators(m: mujoco.MjModel, body: int, where: str) -> tuple[ActuatorGroup, ...]:
    """The vehicle's actuator groups, in action order (sites `<prefix>1..N` on body `body`)."""
    groups = []
    for prefix, kind_name in declared_groups(m, where):
        pattern = re.compile(rf"^{prefix}(\d+)$")
        sites = {}
        for i in range(m.nsite):
            match = pattern.match(m.site(i).name)
            if match:
                sites[int(match.group(1))] = i
        if not sites or sorted(sites) != list(range(1, len(sites) + 1)):
            raise UserError(f"{where}: the sites of actuator group {prefix!r} must be named {prefix}1..{prefix}N, found "
                            f"{[f'{prefix}{k}' for k in sorted(sites)]}")
        ids = [sites[k] for k in sorted(sites)]
        if any(m.site_bodyid[i] != body for i in ids):
            raise UserError(f"{where}: every {prefix} site must belong to the vehicle body")
        settings = {}
        field_prefix = f"{PREFIX}{prefix}:"
        for i in range(m.nnumeric):
            if m.numeric(i).name.startswith(field_prefix):
                settings[m.numeric(i).name[len(field_prefix):]] = np.array(m.numeric(i).data, dtype=np.float64)
        for i in range(m.ntext):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_TEXT, i) or ""
            if name.startswith(field_prefix):
                settings[name[len(field_prefix):]] = custom_text(m, name)
        kind = _KINDS[kind_name]
        design, params = kind.load(m, ids, settings, f"{where}, actuator group {prefix!r} ({kind_name})")
        groups.append(ActuatorGroup(kind=kind, names=tuple(m.site(i).name for i in ids), design=design, params=params))
    return tuple(groups)


def _parts(groups: tuple[ActuatorGroup, ...], x: jnp.ndarray) -> list[jnp.ndarray]:
    """x (..., N) cut into the groups' slices (the array itself for a single group)."""
    if len(groups) == 1:
        return [x]
    out, start = [], 0
    for g in groups:
        out.append(x[..., start : start + g.size])
        start += g.size
    return out


def _join(parts: list[jnp.ndarray]) -> jnp.ndarray:
    return parts[0] if len(parts) == 1 else jnp.concatenate(parts, axis=-1)


def targets(groups: tuple[ActuatorGroup, ...], command: jnp.ndarray) -> jnp.ndarray:
    """(N,) states the actuators settle at under `command` (N,) ∈ [−1, 1], in action order."""
    return _join([g.kind.target(g.design, g.params, c) for g, c in zip(groups, _parts(groups, command))])


def advance(groups: tuple[ActuatorGroup, ...], state: jnp.ndarray, target: jnp.ndarray, dt) -> jnp.ndarray:
    """(N,) actuator states after dt (s) towards `target`."""
    return _join([g.kind.advance(g.design, g.params, s, t, dt)
                  for g, s, t in zip(groups, _parts(groups, state), _parts(groups, target))])


def state_ranges(groups: tuple[ActuatorGroup, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(states at command −1, states at command +1), each (N,) in action order (host arrays)."""
    ranges = [g.kind.state_range(g.design, g.params) for g in groups]
    return np.concatenate([lo for lo, _ in ranges]), np.concatenate([hi for _, hi in ranges])


def wrench(groups: tuple[ActuatorGroup, ...], state: jnp.ndarray, nu_r: jnp.ndarray) -> jnp.ndarray:
    """(6,) body wrench [N, N m about the CG], FLU, of all actuators at `state`, moving at `nu_r`
    (6,) relative to the water (body frame)."""
    total = None
    for g, s in zip(groups, _parts(groups, state)):
        w = g.kind.wrench(g.design, g.params, s, nu_r)
        total = w if total is None else total + w
    return total


__all__ = ["advance", "custom_text", "state_ranges", "targets", "wrench", "ActuatorGroup", "ActuatorKind", "allocation_matrix", "declared_groups", "lag_step", "list_kinds",
           "load_actuators", "register_kind"]
