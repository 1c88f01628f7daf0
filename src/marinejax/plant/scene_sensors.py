"""The sensors that see the scene, keyed by name: `altimeter` (a DVL's bottom-lock beams) and
`sonar` (a forward-looking multibeam), each one module with its config section `sensors.<name>`,
off unless `enabled`.

Unlike the navigation sensors (`sensors.py`, used in observation mode "sensors"), these are the
only way a vehicle perceives its surroundings, so an enabled one works in either observation mode:
the env appends its reading to the observation (field `<name>`, `SCENE_SENSOR_FIELDS`) and hands it
to its task in `info["scene_sensors"][name]`.

A sensor class has `measure(cast, rng) -> reading`, `observe(reading) -> (observation_size,)`,
`period` (control steps per update) and `observation_size`; `cast` is the plant's ray cast bound
to the vehicle's current state (`Plant.cast`). Here each sensor updates every `period` steps at a
phase drawn per episode and holds its reading in between. Each draws its random numbers from the
step's key folded with its name, so adding a sensor changes no other sensor's draws.
"""

from __future__ import annotations

import zlib

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.plant.altimeter import Altimeter
from marinejax.plant.sonar import Sonar

SCENE_SENSORS = {"altimeter": Altimeter, "sonar": Sonar}  # name → class; its config is sensors.<name>
# observation field of each: (unit, frame, meaning), as envs.base.OBSERVATION_FIELDS
SCENE_SENSOR_FIELDS = {
    "altimeter": ("m", "body", "altitude along the DVL's axis from its beams (max_range without bottom lock)"),
    "sonar": ("m", "body", "sonar range per beam, right to left across the fan (max_range: no echo)"),
}


@struct.dataclass
class HeldSensor:
    phase: jnp.ndarray  # () int32, update phase (control steps)
    step: jnp.ndarray  # () int32, control steps since the episode start
    reading: object  # the sensor's last reading


def _key(rng: jax.Array, name: str) -> jax.Array:
    return jax.random.fold_in(rng, zlib.crc32(name.encode()) & 0x7FFFFFFF)


class SceneSensors:
    """The enabled scene sensors of one vehicle (`sensors` config), in the order of `SCENE_SENSORS`."""

    def __init__(self, config, control_dt: float):
        self.sensors = {name: cls(getattr(config, name), control_dt) for name, cls in SCENE_SENSORS.items()
                        if getattr(config, name).enabled}

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

    def observation_sizes(self) -> dict[str, int]:
        return {name: sensor.observation_size for name, sensor in self.sensors.items()}

    def observe(self, states: dict[str, HeldSensor]) -> jnp.ndarray:
        """The readings as one vector (the env appends it to the observation)."""
        return jnp.concatenate([sensor.observe(states[name].reading) for name, sensor in self.sensors.items()])
