"""Env names → constructors. Names are `<Vehicle>-<Task>`, e.g. `BlueROV2Heavy-StationKeeping`.

Every task also has a `<Task>Disturbed` variant: the same task whose default config draws, per
episode, new physics (`randomization`), an Ornstein-Uhlenbeck current of up to 0.3 m/s
(`current`) and a constant external force and torque (`disturbance`).
"""

from __future__ import annotations

from typing import Any

from marinejax.envs.base import EnvConfig, MarineEnv
from marinejax.envs.config import apply_overrides
from marinejax.envs.station_keeping import StationKeeping, StationKeepingConfig
from marinejax.envs.tracking import Tracking, TrackingConfig

VEHICLES = {"BlueROV2Heavy": "bluerov2_heavy", "BlueROV2": "bluerov2"}
_BASE_TASKS = {
    "StationKeeping": (StationKeepingConfig, None),
    "CircleTracking": (TrackingConfig, "circle"),
    "HelixTracking": (TrackingConfig, "helix"),
    "LemniscateTracking": (TrackingConfig, "lemniscate"),
}
DISTURBED = {"randomization.enabled": True, "current.mode": "ou", "disturbance.enabled": True}
# task name → (config class, trajectory kind or None for station keeping, default overrides)
TASKS = {
    **{t: (c, k, {}) for t, (c, k) in _BASE_TASKS.items()},
    **{f"{t}Disturbed": (c, k, DISTURBED) for t, (c, k) in _BASE_TASKS.items()},
}


def list_envs() -> list[str]:
    """All registered env names."""
    return [f"{v}-{t}" for v in VEHICLES for t in TASKS]


def _split(name: str) -> tuple[str, str]:
    vehicle, _, task = name.partition("-")
    if vehicle not in VEHICLES or task not in TASKS:
        raise ValueError(f"unknown env {name!r}; registered envs: {list_envs()}")
    return vehicle, task


def get_default_config(name: str) -> EnvConfig:
    """The default (immutable) config of env `name`."""
    _, task = _split(name)
    config_class, _, defaults = TASKS[task]
    return apply_overrides(config_class(), defaults)


def make(name: str, config: EnvConfig | None = None, **overrides: Any) -> MarineEnv:
    """Build env `name` from its default config (or `config`) with validated `overrides`.

    Overrides are keyword arguments naming config fields; nested sections take a mapping, e.g.
    make("BlueROV2Heavy-StationKeeping", episode_length=400, reward={"effort": 0.1},
    current={"mode": "ou"}). Unknown names or keys raise ValueError listing the valid ones.
    """
    vehicle, task = _split(name)
    config_class, kind, _ = TASKS[task]
    config = config or get_default_config(name)
    if not isinstance(config, config_class):
        raise ValueError(f"env {name!r} takes a {config_class.__name__}, got {type(config).__name__}")
    config = apply_overrides(config, overrides)
    if kind is None:
        return StationKeeping(VEHICLES[vehicle], config)
    return Tracking(VEHICLES[vehicle], kind, config)


def register_with_brax() -> None:
    """Make every env available as `brax.envs.get_environment(name, **overrides)`."""
    import functools

    from brax import envs as brax_envs

    for name in list_envs():
        brax_envs.register_environment(name, functools.partial(make, name))
