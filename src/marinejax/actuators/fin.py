"""A control fin (actuator kind "fin"): a rudder, a stern plane, or one of four independent fins
(Fossen 2021 section 8.4.2; the REMUS 100 of the Marine Systems Simulator).

State: deflection δ (rad), lagging its command by a first-order lag (`time_constant`, s); command
u ∈ [−1, 1] sets δ = u · max_angle. The site's +z axis is the lift direction at positive δ, its
position the centre of pressure. With U² = (v·x̂)² + (v·ẑ)², the water speed at `flow_point`
(m, body FLU from the CG; default: the site) in the plane of the body's x axis x̂ and the fin's
lift direction ẑ:

    lift  = ½ ρ U² A C_Lδ δ   along ẑ
    drag  = ½ ρ U² A C_Lδ δ² · drag_factor   along −x̂

with A the fin area (a pair of fins moved together counts both) and C_Lδ the lift slope (per rad).
The moment about the CG is r × F. The lift depends on δ alone, not on the local angle of the flow,
as in the reference: the fin adds no damping. The REMUS reference takes the flow at its centre of
buoyancy and uses the lift slope as the drag coefficient (`drag_factor` 1); its four-fin torpedo
takes the flow in each fin's plane and has no fin drag (`drag_factor` 0).

Signs: a rudder whose site's +z points to port (+y) pushes the tail to port at positive δ, so the
bow turns to starboard (the reference's δ_r > 0); a stern plane whose +z points up lifts the tail,
so the nose goes down and the vehicle dives (the reference's δ_s > 0).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.actuators.base import ActuatorKind, body_wrench, flow_points, scalar_settings, site_frames
from marinejax.errors import UserError

SETTINGS = {"area": 1e-9, "lift_slope": 0.0, "max_angle": 1e-6, "time_constant": 0.0, "drag_factor": 0.0, "fluid_density": 1e-6}
OPTIONAL = ("flow_point",)
MAX_ANGLE = float(np.pi / 2)  # rad: beyond this "deflection" means nothing


@struct.dataclass
class FinDesign:
    position: jnp.ndarray  # (N, 3) m, centre of pressure, body FLU from the CG
    normal: jnp.ndarray  # (N, 3) unit lift direction at positive deflection
    flow_point: jnp.ndarray  # (N, 3) m, where the water velocity is taken
    lift: jnp.ndarray  # () ½ ρ A C_Lδ, N s²/m² per rad
    drag_factor: jnp.ndarray  # ()


@struct.dataclass
class FinParams:
    max_angle: jnp.ndarray  # () rad, deflection at command ±1
    time_constant: jnp.ndarray  # () s
    lift_scale: jnp.ndarray  # (N,) times the nominal lift and drag (1; randomized per episode)


class Fin(ActuatorKind):
    """See the module docstring."""

    name = "fin"

    def load(self, m, sites, settings, where):
        self.check_settings(settings, tuple(SETTINGS) + OPTIONAL, where)
        v = scalar_settings(settings, SETTINGS, OPTIONAL, where)
        if v["max_angle"] > MAX_ANGLE:
            raise UserError(f"{where}: setting 'max_angle' is in rad and must be <= pi/2, got {v['max_angle']}")
        positions, rotations = site_frames(m, sites)
        f32 = lambda a: jnp.asarray(np.float32(a))  # noqa: E731  (host casts: no compiled conversion)
        design = FinDesign(position=f32(positions), normal=f32(rotations[:, :, 2]), flow_point=f32(flow_points(settings, positions, where)),
                           lift=f32(0.5 * v["fluid_density"] * v["area"] * v["lift_slope"]), drag_factor=f32(v["drag_factor"]))
        return design, FinParams(max_angle=f32(v["max_angle"]), time_constant=f32(v["time_constant"]),
                                 lift_scale=f32(np.ones(len(sites))))

    def target(self, design, params, command):
        return jnp.clip(command, -1.0, 1.0) * params.max_angle

    def wrench(self, design, params, state, nu_r):
        v_flow = nu_r[:3] + jnp.cross(nu_r[3:], design.flow_point)  # (N, 3)
        speed_sq = v_flow[:, 0] ** 2 + jnp.sum(v_flow * design.normal, axis=-1) ** 2
        q = design.lift * params.lift_scale * speed_sq  # (N,)
        force = (q * state)[:, None] * design.normal
        force = force.at[:, 0].add(-q * state**2 * design.drag_factor)
        return body_wrench(design.position, force)

    def state_range(self, design, params):
        angle = np.full(design.position.shape[0], float(params.max_angle))
        return -angle, angle

    def describe(self, names, params):
        angle = float(params.max_angle)
        return (f"fin deflection in [-1, 1] of ±{angle:.4g} rad (±{np.degrees(angle):.3g}°; first-order lag; positive "
                f"lifts along the site's +z), order {list(names)}")

    def randomize(self, params, draw, config):
        return params.replace(lift_scale=draw(config.fin_lift_scale, params.lift_scale.shape),
                              time_constant=draw(config.fin_time_constant, ()))

    def privileged(self, params):
        return jnp.concatenate([jnp.stack([params.max_angle, params.time_constant]), params.lift_scale])


def steering_mix(groups) -> np.ndarray:
    """(number of actions, 3): the action for unit commands [rudder, stern planes, propeller] of a
    torpedo whose fins are arranged in any way (a rudder and a stern-plane pair, four independent
    fins, an X tail): each fin whose moment at positive deflection is mostly yaw follows the rudder
    command, signed so that a positive rudder turns the bow to starboard; each fin whose moment is
    mostly pitch follows the stern-plane command, signed so that positive stern planes pitch the
    nose down (the REMUS reference's conventions); propellers follow the third command. With one
    rudder and one stern-plane group it is the identity."""
    rows = []
    for g in groups:
        if g.kind.name == "propeller":
            rows += [[0.0, 0.0, 1.0]] * g.size
        elif g.kind.name == "fin":
            moment = np.cross(np.asarray(g.design.position, float), np.asarray(g.design.normal, float))  # FLU, per unit lift
            for mx, my, mz in moment:
                if abs(mz) >= abs(my):
                    rows.append([-np.sign(mz), 0.0, 0.0])  # negative yaw moment: bow to starboard
                else:
                    rows.append([0.0, np.sign(my), 0.0])  # positive pitch moment (FLU): nose down
        else:
            raise UserError(f"a torpedo is steered by fins and driven by propellers; this one has actuator kind {g.kind.name!r}")
    return np.array(rows, np.float32)
