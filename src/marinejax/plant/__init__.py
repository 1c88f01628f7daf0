"""The plant layer, between `physics` and `envs`: one vehicle with its per-episode parameters.

`Plant` steps a vehicle under explicit `PlantParams` (rigid body, fluid, thrusters, disturbance),
drawn per episode by `Plant.sample_params` (`randomization`, `disturbance`) and with an ocean
current (`current`). Envs, controllers, identification and export build on it; nothing here knows
about tasks or rewards.
"""

from marinejax.plant.current import CurrentConfig, CurrentState
from marinejax.plant.disturbance import DisturbanceConfig
from marinejax.plant.params import PlantParams, apply_params, nominal_params
from marinejax.plant.plant import Plant, PlantConfig, PlantState
from marinejax.plant.randomization import RandomizationConfig

__all__ = [
    "CurrentConfig",
    "CurrentState",
    "DisturbanceConfig",
    "Plant",
    "PlantConfig",
    "PlantParams",
    "PlantState",
    "RandomizationConfig",
    "apply_params",
    "nominal_params",
]
