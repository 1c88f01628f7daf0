"""Domain randomization of a vehicle's physics, per episode (env reset) or per env slot (Brax).

`Dynamics` gathers every randomizable number: rigid body, fluid coefficients and thrusters. The env
draws one per episode when `randomization.enabled` (or keeps the nominal one) and steps with it;
`brax_randomization_fn(config)` returns the `randomization_fn` that `ppo.train` accepts.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import jax
import jax.numpy as jnp
from flax import struct

from marinejax.envs.config import check_range
from marinejax.errors import UserError
from marinejax.hydro.params import HydroParams
from marinejax.thrusters import SUPPLY_VOLTAGE_RANGE
from marinejax.vehicle import VehicleSystem


@dataclasses.dataclass(frozen=True)
class RandomizationConfig:
    """Ranges, drawn uniformly. 'scale' ranges multiply the nominal value (per axis / thruster)."""

    enabled: bool = False
    mass_scale: tuple[float, float] = (0.9, 1.1)
    inertia_scale: tuple[float, float] = (0.8, 1.2)
    net_buoyancy: tuple[float, float] = (-1.5, 1.5)  # N added to buoyancy through the displaced volume
    cob_offset: float = 0.005  # m, each axis of the centre of buoyancy moves by up to ± this
    added_mass_scale: tuple[float, float] = (0.8, 1.2)
    damping_scale: tuple[float, float] = (0.8, 1.2)  # linear and quadratic, per axis
    thruster_gain: tuple[float, float] = (0.9, 1.1)  # per thruster
    thruster_time_constant: tuple[float, float] = (0.03, 0.1)  # s
    voltage: tuple[float, float] = (14.0, 16.8)  # V, supply (a 4S battery from flat to full)

    def __post_init__(self):
        for name in ("mass_scale", "inertia_scale", "added_mass_scale", "damping_scale", "thruster_gain"):
            check_range(f"randomization.{name}", getattr(self, name), low=1e-3)
        check_range("randomization.net_buoyancy", self.net_buoyancy)
        check_range("randomization.thruster_time_constant", self.thruster_time_constant, low=0.0)
        check_range("randomization.voltage", self.voltage, low=SUPPLY_VOLTAGE_RANGE[0])
        if self.voltage[1] > SUPPLY_VOLTAGE_RANGE[1]:
            raise UserError(f"config 'randomization.voltage' must lie in {SUPPLY_VOLTAGE_RANGE} V, got {self.voltage}")
        if not 0 <= self.cob_offset < 0.1:
            raise UserError(f"config 'randomization.cob_offset' must be in [0, 0.1) m, got {self.cob_offset}")


@struct.dataclass
class Dynamics:
    """The physical parameters an episode runs with."""

    mass: jnp.ndarray  # () kg
    inertia: jnp.ndarray  # (3,) kg m^2, principal, about the CG
    hydro: HydroParams
    thruster_gain: jnp.ndarray  # (N,)
    time_constant: jnp.ndarray  # () s
    voltage: jnp.ndarray  # () V


def nominal_dynamics(sys: VehicleSystem) -> Dynamics:
    """The parameters in `sys` (already randomized if Brax swapped in a randomized sys)."""
    return Dynamics(
        mass=sys.model.body_mass[sys.body_id],
        inertia=sys.model.body_inertia[sys.body_id],
        hydro=sys.hydro,
        thruster_gain=sys.thrusters.gain,
        time_constant=sys.thrusters.time_constant,
        voltage=sys.thrusters.voltage,
    )


def sample_dynamics(rng: jax.Array, sys: VehicleSystem, config: RandomizationConfig) -> Dynamics:
    """Perturb the nominal parameters of `sys` with the configured ranges."""
    nom = nominal_dynamics(sys)
    keys = iter(jax.random.split(rng, 10))

    def u(rng_range, shape=()):
        lo, hi = rng_range
        return jax.random.uniform(next(keys), shape, minval=lo, maxval=hi)

    h = nom.hydro
    g = -sys.model.opt.gravity[2]
    mass = nom.mass * u(config.mass_scale)
    # the volume keeps the nominal net buoyancy with the new mass, then shifts it by net_buoyancy
    volume = h.volume + ((mass - nom.mass) * g + u(config.net_buoyancy)) / (h.fluid_density * g)
    damping = u(config.damping_scale, (6,))
    hydro = h.replace(
        added_mass=h.added_mass * u(config.added_mass_scale, (6,)),
        linear_damping=h.linear_damping * damping,
        quadratic_damping=h.quadratic_damping * damping,
        volume=volume,
        center_of_buoyancy=h.center_of_buoyancy + u((-config.cob_offset, config.cob_offset), (3,)),
    )
    return Dynamics(
        mass=mass,
        inertia=nom.inertia * u(config.inertia_scale, (3,)),
        hydro=hydro,
        thruster_gain=nom.thruster_gain * u(config.thruster_gain, nom.thruster_gain.shape),
        time_constant=u(config.thruster_time_constant),
        voltage=u(config.voltage),
    )


def apply_dynamics(sys: VehicleSystem, dyn: Dynamics) -> VehicleSystem:
    """`sys` simulating with the parameters `dyn`."""
    b = sys.body_id
    model = sys.model.replace(
        body_mass=sys.model.body_mass.at[b].set(dyn.mass),
        body_inertia=sys.model.body_inertia.at[b].set(dyn.inertia),
    )
    thrusters = sys.thrusters.replace(gain=dyn.thruster_gain, time_constant=dyn.time_constant, voltage=dyn.voltage)
    return sys.replace(model=model, hydro=dyn.hydro, thrusters=thrusters)


def brax_randomization_fn(config: RandomizationConfig) -> Callable:
    """`randomization_fn(sys, rng) -> (sys_v, in_axes)` for `brax.training.agents.ppo.train`:
    one parameter draw per env slot (kept for the whole training), batched only where it varies."""

    def randomize(sys: VehicleSystem, rng: jax.Array):
        dyn = jax.vmap(lambda k: sample_dynamics(k, sys, config))(rng)
        sys_v = jax.vmap(lambda d: apply_dynamics(sys, d))(dyn)
        sys_v = sys.replace(
            model=sys.model.replace(body_mass=sys_v.model.body_mass, body_inertia=sys_v.model.body_inertia),
            hydro=sys_v.hydro,
            thrusters=sys.thrusters.replace(
                gain=sys_v.thrusters.gain, time_constant=sys_v.thrusters.time_constant, voltage=sys_v.thrusters.voltage
            ),
        )
        none = jax.tree.map(lambda _: None, sys)
        in_axes = none.replace(
            model=none.model.replace(body_mass=0, body_inertia=0),
            hydro=jax.tree.map(lambda _: 0, sys.hydro),
            thrusters=none.thrusters.replace(gain=0, time_constant=0, voltage=0),
        )
        return sys_v, in_axes

    return randomize
