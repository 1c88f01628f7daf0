"""Env names → constructors. Names are `<Vehicle>-<Task>`, e.g. `BlueROV2Heavy-StationKeeping`.

Vehicles are discovered: every MJCF file in `models/mjcf/` is a vehicle, whose envs are named by its
custom text `marinejax:env_name` (else its file stem in CamelCase). Tasks are registered once, in
`marinejax/envs/__init__.py`, with `register_task`; every vehicle gets every task made for its kind
(`marinejax:vehicle_kind`: "rov", the default, or "torpedo"; a task's `vehicle_kinds`); one task name
may have one class per kind (`Docking`: the ROV's landing station, the torpedo's funnel). Every task also
gets a `<Task>Disturbed` variant: the same task whose default config draws, per episode, new
physics (`randomization`), an Ornstein-Uhlenbeck current of up to 0.3 m/s (`current`) and a
constant external force and torque (`disturbance`). `register_environment` adds any other
(name, task, vehicle, config) combination.

The registry is the one piece of module state: it only grows, at import time (tasks) or when a
user registers an env.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Callable

from marinejax.config import apply_overrides
from marinejax.envs.base import EnvConfig, MarineEnv
from marinejax.errors import UserError
from marinejax.vehicle import env_name_prefix, list_vehicles, sensor_settings, vehicle_kind

DISTURBED = {"randomization.enabled": True, "current.mode": "ou", "disturbance.enabled": True}


@dataclasses.dataclass(frozen=True)
class TaskSpec:
    """A registered task: `factory(vehicle, config)` builds the env; `config` is its default."""

    name: str
    factory: Callable[[str, EnvConfig], MarineEnv]
    config: EnvConfig
    vehicle_kinds: tuple[str, ...] = ("rov",)  # the kinds of vehicle that can do it


@dataclasses.dataclass(frozen=True)
class EnvSpec:
    """A registered env: task name, vehicle (MJCF file stem) and default config."""

    name: str
    task: str
    vehicle: str
    config: EnvConfig


_TASKS: dict[str, dict[str, TaskSpec]] = {}  # task name -> vehicle kind -> spec
_CUSTOM_ENVS: dict[str, EnvSpec] = {}


def register_task(name: str, env_class: type[MarineEnv], config: EnvConfig | None = None, **kwargs: Any) -> None:
    """Register task `name` (and `<name>Disturbed`) for every vehicle of env_class.vehicle_kinds:
    env_class(vehicle, config, **kwargs) builds it; `config` defaults to env_class.default_config().
    A name already registered for other kinds gets this class for these kinds."""
    config = config if config is not None else env_class.default_config()
    factory = functools.partial(_build, env_class, kwargs)
    kinds = tuple(env_class.vehicle_kinds)
    for task, default in ((name, config), (f"{name}Disturbed", apply_overrides(config, DISTURBED))):
        taken = set(kinds) & set(_TASKS.get(task, {}))
        if taken:
            raise UserError(f"task {task!r} is already registered for vehicles of kind {sorted(taken)}")
    for task, default in ((name, config), (f"{name}Disturbed", apply_overrides(config, DISTURBED))):
        _TASKS.setdefault(task, {}).update({kind: TaskSpec(task, factory, default, kinds) for kind in kinds})


def _build(env_class: type[MarineEnv], kwargs: dict[str, Any], vehicle: str, config: EnvConfig) -> MarineEnv:
    return env_class(vehicle, config=config, **kwargs)


def register_environment(name: str, task: str, vehicle: str, config: EnvConfig | None = None) -> None:
    """Register env `name`: registered task `task` on vehicle `vehicle` (see `list_vehicles()`) with
    default config `config` (the task's default if None). It is then available to `make`,
    `list_envs` and `marinejax train`; call `register_with_brax()` / `register_gymnasium_envs()` again
    to add it to those registries."""
    if name in list_envs():
        raise UserError(f"env {name!r} is already registered")
    if task not in _TASKS:
        raise UserError(f"unknown task {task!r}; registered tasks: {list(_TASKS)}")
    if vehicle not in list_vehicles():
        raise UserError(f"unknown vehicle {vehicle!r}; available vehicles: {list_vehicles()}")
    _check_kind(task, vehicle)
    default = _TASKS[task][vehicle_kind(vehicle)].config
    if config is not None and type(config) is not type(default):
        raise UserError(f"task {task!r} takes a {type(default).__name__}, got {type(config).__name__}")
    _CUSTOM_ENVS[name] = EnvSpec(name, task, vehicle, config if config is not None else _with_vehicle_sensors(default, vehicle))


def _vehicle_prefixes() -> dict[str, str]:
    """Env-name prefix → vehicle file stem, for every vehicle file."""
    return {env_name_prefix(v): v for v in list_vehicles()}


def _check_kind(task: str, vehicle: str) -> None:
    kinds = list(_TASKS[task])
    if vehicle_kind(vehicle) not in kinds:
        raise UserError(f"task {task!r} is for vehicles of kind {list(kinds)}; {vehicle!r} is a {vehicle_kind(vehicle)!r}")


def list_tasks() -> dict[str, tuple[str, ...]]:
    """Registered task names (with their Disturbed variants) → the vehicle kinds they are for."""
    return {name: tuple(by_kind) for name, by_kind in _TASKS.items()}


def list_envs() -> list[str]:
    """All registered env names: every vehicle × every task for its kind, then the user-registered ones."""
    kinds = {v: vehicle_kind(v) for v in list_vehicles()}
    return [f"{prefix}-{task}" for prefix, vehicle in _vehicle_prefixes().items() for task, by_kind in _TASKS.items()
            if kinds[vehicle] in by_kind] + list(_CUSTOM_ENVS)


def env_spec(name: str) -> EnvSpec:
    """The task, vehicle and default config of env `name`; raises UserError listing the registered envs."""
    if name in _CUSTOM_ENVS:
        return _CUSTOM_ENVS[name]
    prefix, _, task = name.partition("-")
    vehicle = _vehicle_prefixes().get(prefix)
    if vehicle is None or vehicle_kind(vehicle) not in _TASKS.get(task, {}):
        raise UserError(f"unknown env {name!r}; registered envs: {list_envs()}")
    return EnvSpec(name, task, vehicle, _with_vehicle_sensors(_TASKS[task][vehicle_kind(vehicle)].config, vehicle))


def _with_vehicle_sensors(config: EnvConfig, vehicle: str) -> EnvConfig:
    """The task's default config with the vehicle's own sensor parameters (its MJCF), if it has any."""
    settings = sensor_settings(vehicle)
    return apply_overrides(config, {"sensors": settings}) if settings else config


def get_default_config(name: str) -> EnvConfig:
    """The default (immutable) config of env `name`."""
    return env_spec(name).config


def make(name: str, config: EnvConfig | None = None, **overrides: Any) -> MarineEnv:
    """Build env `name` from its default config (or `config`) with validated `overrides`.

    Overrides are keyword arguments naming config fields; nested sections take a mapping, e.g.
    make("BlueROV2Heavy-StationKeeping", episode_length=400, reward={"effort": 0.1},
    current={"mode": "ou"}). Unknown names or keys raise UserError listing the valid ones.
    """
    spec = env_spec(name)
    config = config or spec.config
    if not isinstance(config, type(spec.config)):
        raise UserError(f"env {name!r} takes a {type(spec.config).__name__}, got {type(config).__name__}")
    return _TASKS[spec.task][vehicle_kind(spec.vehicle)].factory(spec.vehicle, apply_overrides(config, overrides))


def register_with_brax() -> None:
    """Make every env available as `brax.envs.get_environment(name, **overrides)`."""
    from brax import envs as brax_envs

    for name in list_envs():
        brax_envs.register_environment(name, functools.partial(make, name))
