"""`PlantParams`: the physical parameters one episode runs with, as an explicit pytree.

This dataclass is the one list of what can differ between episodes (randomization draws every field
of it, `plant.randomization`), and `apply_params` is the one place that writes it into the
`VehicleSystem` the physics step reads. Pass a `PlantParams` to `Plant.step` (or to
`MarineEnv.reset_with_params`) to simulate a vehicle with parameters of your own, e.g. identified ones.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.hydro.params import HydroParams
from marinejax.vehicle import VehicleSystem


@struct.dataclass
class PlantParams:
    """Per-episode physical parameters (leaves may carry leading batch axes)."""

    mass: jnp.ndarray  # () kg
    inertia: jnp.ndarray  # (3,) kg m^2, principal, about the CG
    hydro: HydroParams  # added mass, damping, displaced volume, centre of buoyancy, fluid density
    actuators: tuple  # per actuator group, its kind's episode parameters (a T200Params: gains, lag, voltage)
    disturbance: jnp.ndarray  # (6,) constant external [world-frame force N, body-frame torque N m]
    layout: jnp.ndarray  # (n, 3) m, world: where the scene's movable geoms are (`PlantConfig.movable_geoms`)

    def net_buoyancy(self, gravity: float) -> jnp.ndarray:
        """Buoyancy minus weight, N (positive: the vehicle floats up); gravity in m/s^2."""
        return (self.hydro.fluid_density * self.hydro.volume - self.mass) * gravity


def nominal_params(sys: VehicleSystem) -> PlantParams:
    """The parameters of `sys` as it was loaded, with no external disturbance."""
    return PlantParams(
        mass=sys.model.body_mass[sys.body_id],
        inertia=sys.model.body_inertia[sys.body_id],
        hydro=sys.hydro,
        actuators=tuple(g.params for g in sys.actuators),
        disturbance=jnp.zeros(6),
        layout=sys.model.geom_pos[np.asarray(sys.layout_ids, int)],
    )


def apply_params(sys: VehicleSystem, params: PlantParams) -> VehicleSystem:
    """`sys` simulating with `params` (the disturbance is not part of `sys`: `Plant.step` applies it)."""
    b = sys.body_id
    model = sys.model.replace(
        body_mass=sys.model.body_mass.at[b].set(params.mass),
        body_inertia=sys.model.body_inertia.at[b].set(params.inertia),
    )
    if sys.layout_ids:
        model = model.replace(geom_pos=jnp.asarray(model.geom_pos).at[np.asarray(sys.layout_ids)].set(params.layout))
    groups = tuple(g.replace(params=p) for g, p in zip(sys.actuators, params.actuators))
    return sys.replace(model=model, hydro=params.hydro, actuators=groups)
