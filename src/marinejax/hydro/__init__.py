"""Pure-JAX hydrodynamics of a free-swimming rigid body (Fossen 2021), in the body frame FLU.

`params` holds the per-vehicle coefficients; `forces` the equations of motion and the wrench that
the physics step writes into MuJoCo.
"""

from marinejax.hydro.forces import (
    HydroTerms,
    added_mass_matrix,
    buoyancy_wrench,
    coriolis_force_diagonal,
    coriolis_matrix,
    current_in_body,
    damping_matrix,
    hydro_terms,
    kinetic_energy,
    potential_energy,
    rigid_body_mass_matrix,
    skew,
)
from marinejax.hydro.params import HydroParams

__all__ = [
    "HydroParams",
    "HydroTerms",
    "added_mass_matrix",
    "buoyancy_wrench",
    "coriolis_force_diagonal",
    "coriolis_matrix",
    "current_in_body",
    "damping_matrix",
    "hydro_terms",
    "kinetic_energy",
    "potential_energy",
    "rigid_body_mass_matrix",
    "skew",
]
