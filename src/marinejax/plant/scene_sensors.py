"""The sensors that see the scene, keyed by name: `altimeter` (a DVL's bottom-lock beams) and
`sonar` (a forward-looking multibeam), each one module with its config section `sensors.<name>`,
off unless `enabled`.

Unlike the navigation sensors (`sensors.py`, used in observation mode "sensors"), these are the
only way a vehicle perceives its surroundings, so an enabled one works in either observation mode:
the env appends its reading to the observation (field `<name>`) and hands it to its task in
`info["scene_sensors"][name]`.

A scene sensor is a section of the sensors config whose config has the property `sensor`: the class
that implements it, constructed as `sensor(config, control_dt)`, with `measure(cast, rng) ->
reading`, `observe(reading) -> (observation_size,)`, `period` (control steps per update),
`observation_size` and `field` (unit, frame, meaning of its observation field) or, for an
observation of several fields, `fields` (field name → (size, (unit, frame, meaning)), in the
observation's order; the sonar with intensities: `sonar`, then `sonar_intensity`); `cast` is the
plant's ray cast bound to the vehicle's current state (`Plant.cast`). A new one is one module (its
config and class) plus a field in a subclass of `SensorConfig` (`tests/test_scene_sensors.py` adds
an echo sounder so). Here each sensor updates every `period` steps at a phase drawn per episode and
holds its reading in between. Each draws its random numbers from the step's key folded with its
name, so adding a sensor changes no other sensor's draws.
"""

from __future__ import annotations

import dataclasses
import zlib

import jax
import jax.numpy as jnp
from flax import struct


def scene_sensor_configs(config) -> dict[str, object]:
    """The scene sensors' sections of the sensors config `config`, enabled or not: name → config."""
    sections = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)}
    return {name: section for name, section in sections.items() if hasattr(section, "sensor")}


@struct.dataclass
class HeldSensor:
    phase: jnp.ndarray  # () int32, update phase (control steps)
    step: jnp.ndarray  # () int32, control steps since the episode start
    reading: object  # the sensor's last reading


def _key(rng: jax.Array, name: str) -> jax.Array:
    return jax.random.fold_in(rng, zlib.crc32(name.encode()) & 0x7FFFFFFF)


class SceneSensors:
    """The enabled scene sensors of one vehicle (`sensors` config), in the order of its sections."""

    def __init__(self, config, control_dt: float):
        self.sensors = {name: section.sensor(section, control_dt) for name, section in scene_sensor_configs(config).items()
                        if section.enabled}

    def __bool__(self) -> bool:
        return bool(self.sensors)

    def init(self, rng: jax.Array, cast) -> dict[str, HeldSensor]:
        """Every sensor's first reading (all update at the episode start) and its phase."""
        out = {}
        for name, sensor in self.sensors.items():
            k_phase, k_measure = jax.random.split(_key(rng, name))
            phase = jax.random.randint(k_phase, (), 0, sensor.period)
            out[name] = HeldSensor(phase=phase, step=jnp.zeros((), jnp.int32), reading=sensor.measure(cast, k_measure))
        return out

    def step(self, states: dict[str, HeldSensor], cast, rng: jax.Array) -> dict[str, HeldSensor]:
        """The readings one control step later."""
        out = {}
        for name, sensor in self.sensors.items():
            held = states[name]
            step = held.step + 1
            new = sensor.measure(cast, _key(rng, name))
            if sensor.period > 1:
                update = (step + held.phase) % sensor.period == 0
                new = jax.tree.map(lambda n, o: jnp.where(update, n, o), new, held.reading)
            out[name] = held.replace(step=step, reading=new)
        return out

    def _fields(self) -> dict[str, tuple[int, tuple[str, str, str]]]:
        out = {}
        for name, sensor in self.sensors.items():
            out.update(getattr(sensor, "fields", None) or {name: (sensor.observation_size, sensor.field)})
        return out

    def observation_sizes(self) -> dict[str, int]:
        """Each observation field's size, in the observation's order: name → size."""
        return {name: size for name, (size, _) in self._fields().items()}

    def observation_fields(self) -> dict[str, tuple[str, str, str]]:
        """Each observation field's description: name → (unit, frame, meaning)."""
        return {name: described for name, (_, described) in self._fields().items()}

    def observe(self, states: dict[str, HeldSensor]) -> jnp.ndarray:
        """The readings as one vector (the env appends it to the observation)."""
        return jnp.concatenate([sensor.observe(states[name].reading) for name, sensor in self.sensors.items()])

    def observe_fields(self, states: dict[str, HeldSensor]) -> dict[str, jnp.ndarray]:
        """The readings by observation field: name → its part of `observe` (e.g. "sonar": the ranges)."""
        out, start, whole = {}, 0, self.observe(states)
        for name, size in self.observation_sizes().items():
            out[name] = whole[start : start + size]
            start += size
        return out
