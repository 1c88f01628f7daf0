"""marinejax: underwater vehicles in JAX and MuJoCo MJX, with Fossen hydrodynamics.

Layers, each importing only those before it: vehicle (MJCF + parameters) → hydro (forces) →
physics (MJX step, rollout) → envs (tasks, wrappers, Gymnasium adapter) → train (PPO, CLI).
"""

from marinejax import _compat
from marinejax._quiet_import import import_mjx_quietly

import_mjx_quietly()  # before anything imports brax or mujoco.mjx
_compat.install()  # jax.device_put_replicated for brax 0.14.2 on jax >= 0.10 (only where missing)

from marinejax.envs import get_default_config, list_envs, make
from marinejax.envs.gym_adapter import register_gymnasium_envs
from marinejax.physics import (
    PhysicsState,
    SimulationDiverged,
    Trajectory,
    VehicleState,
    control_step,
    initial_state,
    rollout,
)
from marinejax.vehicle import Vehicle, VehicleSystem, list_vehicles, load_vehicle

__version__ = "0.1.0"

__all__ = [
    "PhysicsState",
    "SimulationDiverged",
    "Trajectory",
    "Vehicle",
    "VehicleState",
    "VehicleSystem",
    "control_step",
    "get_default_config",
    "initial_state",
    "list_envs",
    "list_vehicles",
    "load_vehicle",
    "make",
    "rollout",
]

# Every env is also a Gymnasium id, "marinejax/<name>-v0" (gymnasium.make / make_vec).
register_gymnasium_envs()
