"""marinejax: underwater vehicles in JAX and MuJoCo MJX, with Fossen hydrodynamics."""

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
    "initial_state",
    "list_vehicles",
    "load_vehicle",
    "rollout",
]
