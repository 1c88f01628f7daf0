"""Domain randomization: the ranges of the physical parameters and the draw of one episode's set.

`sample_dynamics` perturbs every physical field of `PlantParams` (`plant.params`) within the
configured ranges; `Plant.sample_params` calls it at each episode when `randomization.enabled`.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from marinejax.config import check_range
from marinejax.errors import UserError
from marinejax.plant.params import PlantParams
from marinejax.actuators.t200 import SUPPLY_VOLTAGE_RANGE


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
    # actuators (read by the kinds' `randomize`): T200 thrusters
    thruster_gain: tuple[float, float] = (0.9, 1.1)  # per thruster
    thruster_time_constant: tuple[float, float] = (0.03, 0.1)  # s
    voltage: tuple[float, float] = (14.0, 16.8)  # V, supply (a 4S battery from flat to full)
    # fins and propellers (torpedo AUVs)
    fin_lift_scale: tuple[float, float] = (0.8, 1.2)  # per fin, times its lift (and drag): fouling, a bent fin, a lift slope that is a fit
    fin_time_constant: tuple[float, float] = (0.05, 0.2)  # s, servo lag
    propeller_thrust_scale: tuple[float, float] = (0.9, 1.1)  # times the thrust at a given shaft speed and flow
    propeller_time_constant: tuple[float, float] = (0.5, 1.5)  # s, shaft speed lag

    def __post_init__(self):
        for name in ("mass_scale", "inertia_scale", "added_mass_scale", "damping_scale", "thruster_gain", "fin_lift_scale",
                     "propeller_thrust_scale"):
            check_range(f"randomization.{name}", getattr(self, name), low=1e-3)
        check_range("randomization.net_buoyancy", self.net_buoyancy)
        for name in ("thruster_time_constant", "fin_time_constant", "propeller_time_constant"):
            check_range(f"randomization.{name}", getattr(self, name), low=0.0)
        check_range("randomization.voltage", self.voltage, low=SUPPLY_VOLTAGE_RANGE[0])
        if self.voltage[1] > SUPPLY_VOLTAGE_RANGE[1]:
            raise UserError(f"config 'randomization.voltage' must lie in {SUPPLY_VOLTAGE_RANGE} V, got {self.voltage}")
        if not 0 <= self.cob_offset < 0.1:
            raise UserError(f"config 'randomization.cob_offset' must be in [0, 0.1) m, got {self.cob_offset}")


def sample_dynamics(rng: jax.Array, nom: PlantParams, kinds: tuple, gravity: float,
                    config: RandomizationConfig) -> PlantParams:
    """`nom` with its physical parameters perturbed within the configured ranges (gravity in m/s^2;
    the disturbance is left as it is). `kinds`: the `ActuatorKind` of each of `nom.actuators`,
    which draws that group's parameters (after the rigid-body and fluid ones, in group order)."""
    keys = _KeyStream(rng)

    def u(rng_range, shape=()):
        lo, hi = rng_range
        return jax.random.uniform(next(keys), shape, minval=lo, maxval=hi)

    h = nom.hydro
    g = gravity
    mass = nom.mass * u(config.mass_scale)
    # the volume keeps the nominal net buoyancy with the new mass, then shifts it by net_buoyancy
    volume = h.volume + ((mass - nom.mass) * g + u(config.net_buoyancy)) / (h.fluid_density * g)
    damping = u(config.damping_scale, (6,))
    added_scale = u(config.added_mass_scale, (6,))
    if not h.simple:  # S^½ M_A S^½: the couplings scale with their two axes, M_A stays positive definite
        root = jnp.sqrt(added_scale)
        h = h.replace(added_mass_coupling=h.added_mass_coupling * root[..., :, None] * root[..., None, :])
    hydro = h.replace(
        added_mass=h.added_mass * added_scale,
        linear_damping=h.linear_damping * damping,
        quadratic_damping=h.quadratic_damping * damping,
        volume=volume,
        center_of_buoyancy=h.center_of_buoyancy + u((-config.cob_offset, config.cob_offset), (3,)),
    )
    inertia = nom.inertia * u(config.inertia_scale, (3,))
    actuators = tuple(kind.randomize(p, u, config) for kind, p in zip(kinds, nom.actuators))
    return nom.replace(mass=mass, inertia=inertia, hydro=hydro, actuators=actuators)


class _KeyStream:
    """Keys for the draws in a fixed order: the first ten from split(rng, 10), then more folded in
    by index (so a vehicle with more actuator groups leaves the earlier draws unchanged)."""

    def __init__(self, rng: jax.Array):
        self._rng, self._first, self._i = rng, jax.random.split(rng, 10), 0

    def __iter__(self):
        return self

    def __next__(self) -> jax.Array:
        i, self._i = self._i, self._i + 1
        return self._first[i] if i < 10 else jax.random.fold_in(self._rng, i)
