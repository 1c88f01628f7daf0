"""A propeller on a shaft (actuator kind "propeller"): thrust and torque from open-water
coefficients linear in the advance ratio (Wageningen B-series fit, Fossen 2021 section 9.5; the
REMUS 100 of the Marine Systems Simulator).

State: shaft speed n (rev/min), lagging its command by a first-order lag (`time_constant`, s).
Command u ∈ [−1, 1] sets n = min_rpm + (u + 1)/2 · (max_rpm − min_rpm). The site's +z axis is the
thrust direction at positive n; its position the point of action (the shaft line).

    n_s = n/60 (rev/s),  V_a = (1 − w) U,  J = V_a/(n_s D)
    K_T = K_T0 + (K_T,max − K_T0) J / J_max,  K_Q likewise
    thrust T = ρ D⁴ K_T |n_s| n_s,  torque Q = ρ D⁵ K_Q |n_s| n_s    (n_s > 0)
    thrust T = ρ D⁴ K_T0 |n_s| n_s,  torque Q = ρ D⁵ K_Q0 |n_s| n_s   (n_s ≤ 0: the bollard values)

U is the water speed |v_r| at `flow_point` (m, body FLU from the CG; default: the site). The hull
receives (1 − t) T along the axis (thrust deduction t) and `torque_scale` · Q about it. The REMUS
reference takes U as the vehicle's absolute speed at its centre of buoyancy (the same in still
water; in a current the propeller sees the water, as here) and applies a tenth of the torque in the
direction of the shaft's rotation (`torque_scale` 0.1; "to match experimental results"); a
reaction torque of the full size opposes the rotation: `torque_scale` −1.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.actuators.base import ActuatorKind, body_wrench, flow_points, scalar_settings, site_frames
from marinejax.errors import UserError

SETTINGS = {  # name → lower bound (None: any finite number)
    "diameter": 1e-6, "kt0": None, "kq0": None, "kt_max": None, "kq_max": None, "j_max": 1e-6, "wake_fraction": 0.0,
    "thrust_deduction": 0.0, "torque_scale": None, "min_rpm": None, "max_rpm": None, "time_constant": 0.0, "fluid_density": 1e-6,
}
OPTIONAL = ("flow_point",)


@struct.dataclass
class PropellerDesign:
    position: jnp.ndarray  # (N, 3) m, body FLU from the CG
    axis: jnp.ndarray  # (N, 3) unit thrust direction, body FLU
    flow_point: jnp.ndarray  # (N, 3) m, where the inflow speed is taken
    rho_d4: jnp.ndarray  # () ρ D⁴, kg m
    rho_d5: jnp.ndarray  # () ρ D⁵, kg m²
    diameter: jnp.ndarray  # () m
    kt0: jnp.ndarray
    kq0: jnp.ndarray
    kt_slope: jnp.ndarray  # dK_T/dJ
    kq_slope: jnp.ndarray  # dK_Q/dJ
    wake_fraction: jnp.ndarray
    thrust_deduction: jnp.ndarray
    torque_scale: jnp.ndarray


@struct.dataclass
class PropellerParams:
    min_rpm: jnp.ndarray  # () rev/min at command −1
    max_rpm: jnp.ndarray  # () rev/min at command +1
    time_constant: jnp.ndarray  # () s
    thrust_scale: jnp.ndarray  # () times the nominal thrust (1; randomized per episode)


class Propeller(ActuatorKind):
    """See the module docstring."""

    name = "propeller"

    def load(self, m, sites, settings, where):
        self.check_settings(settings, tuple(SETTINGS) + OPTIONAL, where)
        v = scalar_settings(settings, SETTINGS, OPTIONAL, where)
        if not v["min_rpm"] < v["max_rpm"]:
            raise UserError(f"{where}: min_rpm ({v['min_rpm']}) must be below max_rpm ({v['max_rpm']})")
        positions, rotations = site_frames(m, sites)
        f32 = lambda a: jnp.asarray(np.float32(a))  # noqa: E731  (host casts: no compiled conversion)
        rho, d = v["fluid_density"], v["diameter"]
        design = PropellerDesign(
            position=f32(positions), axis=f32(rotations[:, :, 2]), flow_point=f32(flow_points(settings, positions, where)),
            rho_d4=f32(rho * d**4), rho_d5=f32(rho * d**5), diameter=f32(d), kt0=f32(v["kt0"]), kq0=f32(v["kq0"]),
            kt_slope=f32((v["kt_max"] - v["kt0"]) / v["j_max"]), kq_slope=f32((v["kq_max"] - v["kq0"]) / v["j_max"]),
            wake_fraction=f32(v["wake_fraction"]), thrust_deduction=f32(v["thrust_deduction"]), torque_scale=f32(v["torque_scale"]))
        params = PropellerParams(min_rpm=f32(v["min_rpm"]), max_rpm=f32(v["max_rpm"]), time_constant=f32(v["time_constant"]),
                                thrust_scale=f32(1.0))
        return design, params

    def target(self, design, params, command):
        u = jnp.clip(command, -1.0, 1.0)
        return params.min_rpm + 0.5 * (u + 1.0) * (params.max_rpm - params.min_rpm)

    def thrust_torque(self, design, state, nu_r):
        """(thrust (N,) N, torque (N,) N m) of each propeller at shaft speed `state` (rev/min)."""
        n = state / 60.0
        v_flow = nu_r[:3] + jnp.cross(nu_r[3:], design.flow_point)  # (N, 3) water-relative velocity
        v_a = (1.0 - design.wake_fraction) * jnp.linalg.norm(v_flow, axis=-1)
        forward = n > 0
        # K(J) n² written as K0 |n| n + slope (V_a/D) |n|: no division by n near zero
        j_term = jnp.where(forward, (v_a / design.diameter) * jnp.abs(n), 0.0)
        thrust = design.rho_d4 * (design.kt0 * jnp.abs(n) * n + design.kt_slope * j_term)
        torque = design.rho_d5 * (design.kq0 * jnp.abs(n) * n + design.kq_slope * j_term)
        return thrust, torque

    def wrench(self, design, params, state, nu_r):
        thrust, torque = self.thrust_torque(design, state, nu_r)
        force = ((1.0 - design.thrust_deduction) * thrust * params.thrust_scale)[:, None] * design.axis
        return body_wrench(design.position, force, (design.torque_scale * torque)[:, None] * design.axis)

    def state_range(self, design, params):
        n = design.position.shape[0]
        return np.full(n, float(params.min_rpm)), np.full(n, float(params.max_rpm))

    def describe(self, names, params):
        return (f"propeller speed in [-1, 1]: -1 = {float(params.min_rpm):.6g} rev/min, +1 = {float(params.max_rpm):.6g} "
                f"rev/min (first-order lag; positive speed pushes along the site's +z), order {list(names)}")

    def randomize(self, params, draw, config):
        return params.replace(thrust_scale=draw(config.propeller_thrust_scale, ()),
                              time_constant=draw(config.propeller_time_constant, ()))

    def privileged(self, params):
        return jnp.stack([params.max_rpm, params.time_constant, params.thrust_scale])
