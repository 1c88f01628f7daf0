"""The plant layer, between `physics` and `envs`: one vehicle with its per-episode parameters.

`Plant` steps a vehicle under explicit `PlantParams` (rigid body, fluid, thrusters, disturbance),
drawn per episode by `Plant.sample_params` (`randomization`, `disturbance`) and with an ocean
current (`current`). `sensors` models what the vehicle measures and `estimator` the filter it runs
on those measurements (`Plant.sensors`). Envs, controllers, identification and export build on it; nothing here knows
about tasks or rewards.
"""

from marinejax.plant.current import CurrentConfig, CurrentState
from marinejax.plant.disturbance import DisturbanceConfig
from marinejax.plant.params import PlantParams, apply_params, nominal_params
from marinejax.plant.plant import Plant, PlantConfig, PlantState
from marinejax.plant.randomization import RandomizationConfig
from marinejax.plant.scene_sensors import SceneSensors
from marinejax.plant.sensors import Measurement, SensorConfig, SensorParams, SensorState, SensorSuite

__all__ = [
    "CurrentConfig",
    "CurrentState",
    "DisturbanceConfig",
    "Plant",
    "PlantConfig",
    "PlantParams",
    "PlantState",
    "Measurement",
    "RandomizationConfig",
    "SceneSensors",
    "SensorConfig",
    "SensorParams",
    "SensorState",
    "SensorSuite",
    "apply_params",
    "nominal_params",
]
