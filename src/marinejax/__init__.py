"""marinejax: underwater vehicles in JAX and MuJoCo MJX, with Fossen hydrodynamics.

Layers, each importing only those before it: vehicle (MJCF + parameters) → hydro (forces) →
physics (MJX step, rollout) → envs (tasks, wrappers, Gymnasium adapter) → train (PPO, CLI).

Importing marinejax prints nothing, registers every env with Brax and Gymnasium, and on jax >= 0.10
adds `jax.device_put_replicated`, which brax 0.14.2 still calls (`marinejax._compat`).
"""

from marinejax import _compat
from marinejax._quiet_import import import_mjx_quietly

import_mjx_quietly()  # before anything imports brax or mujoco.mjx
_compat.install()  # jax.device_put_replicated for brax 0.14.2 on jax >= 0.10 (only where missing)

from marinejax.envs import get_default_config, list_envs, make, register_with_brax
from marinejax.envs.gym_adapter import register_gymnasium_envs
from marinejax.errors import UserError
from marinejax.physics import (
    PhysicsState,
    SimulationDiverged,
    Trajectory,
    VehicleState,
    control_step,
    initial_state,
    rollout,
)
from marinejax.scene import list_scenes
from marinejax.vehicle import Vehicle, VehicleSystem, list_vehicles, load_vehicle

from marinejax._version import __version__ as __version__

__all__ = [
    "PhysicsState",
    "SimulationDiverged",
    "UserError",
    "Trajectory",
    "Vehicle",
    "VehicleState",
    "VehicleSystem",
    "control_step",
    "get_default_config",
    "initial_state",
    "list_envs",
    "list_scenes",
    "list_vehicles",
    "load_vehicle",
    "make",
    "rollout",
]

# Importing marinejax registers every env, by name, with Brax (brax.envs.get_environment(name)) and
# Gymnasium ("marinejax/<name>-v0" for gymnasium.make / make_vec): what users of those registries
# expect from an env package. Both only add entries and can be called again (they are idempotent).
register_with_brax()
register_gymnasium_envs()
