"""Immutable env configs and validated overrides.

Configs are frozen dataclasses (nested by topic). `apply_overrides(config, {"reward": {"effort": 0.1}})`
or with dotted keys `{"reward.effort": 0.1}` returns a new config; an unknown key is an error
listing the valid ones, and a value of the wrong kind is an error naming the field.
"""

from __future__ import annotations

import ast

import dataclasses
import math
from typing import Any, Mapping, TypeVar

from marinejax.errors import UserError

C = TypeVar("C")


class UnknownConfigKey(UserError):
    """An override names a config field that does not exist (the message lists the valid ones);
    `key` is the unknown key, dotted from the top of the config."""

    def __init__(self, message: str, key: str):
        super().__init__(message)
        self.key = key


def _check_value(path: str, old: Any, new: Any, variable_length: bool = False) -> Any:
    if dataclasses.is_dataclass(old):
        if isinstance(new, Mapping):
            return apply_overrides(old, new, prefix=path + ".")
        if isinstance(new, type(old)):  # the section itself, or a subclass's (one that adds a scene sensor)
            return new
        raise UserError(f"config '{path}' is a section; pass a mapping of its fields or a {type(old).__name__}, got {new!r}")
    if isinstance(old, bool):
        if not isinstance(new, bool):
            raise UserError(f"config '{path}' must be true or false, got {new!r}")
        return new
    if isinstance(old, (int, float)) and not isinstance(old, bool):
        if isinstance(new, bool) or not isinstance(new, (int, float)):
            raise UserError(f"config '{path}' must be a number, got {new!r}")
        if not math.isfinite(new):
            raise UserError(f"config '{path}' must be finite, got {new!r}")
        if isinstance(old, int) and not float(new).is_integer():
            raise UserError(f"config '{path}' must be an integer, got {new!r}")
        return type(old)(new)
    if isinstance(old, tuple):
        if variable_length and old and isinstance(new, (tuple, list)) and len(new) >= 1:
            return tuple(_check_value(f"{path}[{i}]", old[0], n) for i, n in enumerate(new))
        if not isinstance(new, (tuple, list)) or len(new) != len(old):
            raise UserError(f"config '{path}' must be a sequence of {len(old)} values, got {new!r}")
        return tuple(_check_value(f"{path}[{i}]", o, n) for i, (o, n) in enumerate(zip(old, new)))
    if isinstance(old, str) or old is None:
        if not (isinstance(new, str) or new is None):
            raise UserError(f"config '{path}' must be a string, got {new!r}")
        return new
    return new


def apply_overrides(config: C, overrides: Mapping[str, Any], prefix: str = "") -> C:
    """New config with `overrides` applied (nested mappings or dotted keys); validated."""
    nested: dict[str, Any] = {}
    for key, value in overrides.items():
        head, _, rest = key.partition(".")
        if rest:
            sub = nested.setdefault(head, {})
            if not isinstance(sub, dict):
                raise UserError(f"config '{prefix}{head}' given both as a value and as a section")
            sub[rest] = value
        else:
            if isinstance(nested.get(head), dict) and not isinstance(value, Mapping):
                raise UserError(f"config '{prefix}{head}' given both as a value and as a section")
            nested[head] = value
    fields = {f.name: f for f in dataclasses.fields(config)}
    valid = list(fields)
    changes = {}
    for key, value in nested.items():
        if key not in valid:
            raise UnknownConfigKey(f"unknown config key '{prefix}{key}'; valid keys{' of ' + prefix[:-1] if prefix else ''}: {valid}",
                                   key=prefix + key)
        variable = bool(fields[key].metadata.get("variable_length"))
        changes[key] = _check_value(prefix + key, getattr(config, key), value, variable)
    return dataclasses.replace(config, **changes)


def to_dict(config: Any) -> dict[str, Any]:
    """Plain nested dict of a config (for logging and run directories)."""
    return dataclasses.asdict(config)


def check_fields(section: str, config: Any, strict: bool = False, zero_allowed: tuple[str, ...] = ()) -> None:
    """Raise UserError unless every numeric field of the dataclass `config` is finite and >= 0
    (> 0 when `strict`, except the fields named in `zero_allowed`); `section` is the dotted config
    key of `config` for the message."""
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        positive = strict and f.name not in zero_allowed
        if not (math.isfinite(value) and (value > 0 if positive else value >= 0)):
            raise UserError(f"config '{section}.{f.name}' must be finite and {'>' if positive else '>='} 0, got {value!r}")


def check_range(name: str, value: Any, low: float | None = None, positive: bool = False) -> None:
    """Raise UserError unless value is a finite (lo, hi) with lo <= hi (and lo >= low when given,
    lo > 0 when `positive`); `name` is the dotted config key for the message."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise UserError(f"config '{name}' must be a range (low, high), got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise UserError(f"config '{name}' must be a finite range (low, high) with low <= high, got {value!r}")
    if low is not None and lo < low:
        raise UserError(f"config '{name}' must not go below {low}, got {value!r}")
    if positive and lo <= 0:
        raise UserError(f"config '{name}' must be > 0, got {value!r}")


def check_nonnegative(config: Any, names: tuple[str, ...], label: str = "config") -> None:
    """Raise UserError unless each named field of `config` is finite and >= 0 (every entry, for a
    tuple); `label` names the config in the message."""
    for name in names:
        value = getattr(config, name)
        if not all(math.isfinite(v) and v >= 0 for v in (value if isinstance(value, tuple) else (value,))):
            raise UserError(f"{label} '{name}' must be finite and >= 0, got {value}")


def parse_key_values(items: list[str] | None, flag: str) -> dict[str, Any]:
    """Parse KEY=VALUE strings; VALUE is true/false, a Python literal (number, bool, tuple, string) or a bare string."""
    out = {}
    for item in items or []:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise UserError(f"{flag} expects KEY=VALUE, got {item!r}")
        if raw.strip().lower() in ("true", "false"):
            out[key.strip()] = raw.strip().lower() == "true"
            continue
        try:
            value = ast.literal_eval(raw)
        except (ValueError, SyntaxError):
            value = raw
        out[key.strip()] = value
    return out
