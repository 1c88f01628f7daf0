"""Forces on a slender (torpedo) hull that a diagonal Fossen model lacks: lift and drag in the
vertical plane, and cross-flow drag by strip theory (Fossen 2021, sections 8.4.2 and 6.7; the REMUS
100 model of the Marine Systems Simulator).

All of it acts about the vehicle's hydrodynamic reference point (`HydroParams.reference_point`, the
REMUS model's CO = CB) and is evaluated there on the relative velocity ν_r = [v_r, ω] (body frame
FLU, m/s and rad/s); the wrench returned is about that point, body frame FLU.

Lift and drag: the hull is a wing of area S and span b (AR = b²/S) at the angle of attack
α = atan2(w_r, u_r); C_L = C_Lα α with C_Lα = π AR / (1 + sqrt(1 + (AR/2)²)), C_D = C_D0 + C_L²/(π e AR),
forces ½ρU_r²S C_{L,D} turned from flow to body axes. The reference applies them at the reference
point (no pitch moment) and only in the vertical plane; so does this module.

Cross-flow drag: strips of the hull of height T at positions x_i (along the body x axis, from the
reference point) with weights dx_i, 2-D drag coefficient C_d: sway and yaw from
(v_r + x_i r)|v_r + x_i r|; with `crossflow_heave` also heave and pitch from (w_r − x_i q)|w_r − x_i q|
(the reference applies it in sway and yaw only, so its heave and pitch have no quadratic damping).
`crossflow_reference_strips` reproduces the reference's strips: n + 1 strips of full weight L/n at
−L/2, …, +L/2 (1.05 L in all); without it, n strips at the cell centres (the hull's length).
"""

from __future__ import annotations

from typing import Mapping

import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.errors import UserError

# file fields (a parameter set's `marinejax:<set>:<field>`, one number each); all or none must be given
FIELDS = (
    "hull_lift_area",  # S, m²
    "hull_span",  # b, m
    "hull_drag_coefficient",  # C_D0 on the area S
    "hull_oswald_efficiency",  # e
    "crossflow_drag_coefficient",  # 2-D C_d of a hull section
    "crossflow_height",  # T, m: the projected height of a section
    "crossflow_length",  # L, m: the length the strips cover, centred on the reference point
    "crossflow_strips",  # n
    "crossflow_heave",  # 1: also in heave and pitch; 0: sway and yaw only (the reference)
    "crossflow_reference_strips",  # 1: the reference's n + 1 full-weight strips; 0: n cell centres
)


@struct.dataclass
class HullParams:
    """Slender-hull coefficients (module docstring); lengths in m, areas in m², along body FLU."""

    lift_area: jnp.ndarray  # () S, m²
    span: jnp.ndarray  # () b, m
    drag_coefficient: jnp.ndarray  # () C_D0
    oswald_efficiency: jnp.ndarray  # () e
    crossflow_drag_coefficient: jnp.ndarray  # () C_d
    crossflow_height: jnp.ndarray  # () T, m
    strip_x: jnp.ndarray  # (n,) m, strip positions along body x from the reference point
    strip_dx: jnp.ndarray  # (n,) m, strip lengths
    crossflow_heave: bool = struct.field(pytree_node=False, default=False)

    @classmethod
    def from_mapping(cls, values: Mapping[str, np.ndarray], source: str) -> "HullParams | None":
        """The hull terms of a parameter set (None when it has none of the hull fields)."""
        given = {k: np.asarray(values[k], np.float64).reshape(-1) for k in FIELDS if k in values}
        if not given:
            return None
        missing = sorted(set(FIELDS) - set(given))
        if missing:
            raise UserError(f"{source}: a slender hull needs all of {sorted(FIELDS)}; missing {missing}")
        for k, v in given.items():
            if v.size != 1 or not np.isfinite(v[0]) or v[0] < 0:
                raise UserError(f"{source}: '{k}' must be one finite number >= 0, got {v.tolist()}")
        v = {k: float(x[0]) for k, x in given.items()}
        n = int(round(v["crossflow_strips"]))
        if n < 1 or n != v["crossflow_strips"]:
            raise UserError(f"{source}: 'crossflow_strips' must be a positive integer, got {v['crossflow_strips']}")
        for k in ("crossflow_heave", "crossflow_reference_strips"):
            if v[k] not in (0.0, 1.0):
                raise UserError(f"{source}: '{k}' must be 0 or 1, got {v[k]}")
        for k in ("hull_lift_area", "hull_span", "hull_oswald_efficiency"):
            if v[k] <= 0:
                raise UserError(f"{source}: '{k}' must be > 0, got {v[k]}")
        length = v["crossflow_length"]
        if v["crossflow_reference_strips"]:
            x, dx = np.linspace(-length / 2, length / 2, n + 1), np.full(n + 1, length / n)
        else:
            x, dx = -length / 2 + (np.arange(n) + 0.5) * length / n, np.full(n, length / n)
        f32 = lambda a: jnp.asarray(np.float32(a))  # noqa: E731  (host casts: no compiled conversion)
        return cls(lift_area=f32(v["hull_lift_area"]), span=f32(v["hull_span"]), drag_coefficient=f32(v["hull_drag_coefficient"]),
                   oswald_efficiency=f32(v["hull_oswald_efficiency"]), crossflow_drag_coefficient=f32(v["crossflow_drag_coefficient"]),
                   crossflow_height=f32(v["crossflow_height"]), strip_x=f32(x), strip_dx=f32(dx),
                   crossflow_heave=bool(v["crossflow_heave"]))


def lift_drag(hull: HullParams, density, nu_r: jnp.ndarray) -> jnp.ndarray:
    """(6,) hull lift and drag wrench about the reference point, body FLU, at relative velocity nu_r (6,)."""
    u, w = nu_r[0], nu_r[2]
    speed_sq = nu_r[0] ** 2 + nu_r[1] ** 2 + nu_r[2] ** 2
    # Fossen's α = atan2(w_r, u_r) with w down (FRD): in FLU w_FRD = −w
    alpha = jnp.arctan2(-w, u)
    aspect = hull.span**2 / hull.lift_area
    cl = jnp.pi * aspect / (1.0 + jnp.sqrt(1.0 + (aspect / 2.0) ** 2)) * alpha
    cd = hull.drag_coefficient + cl**2 / (jnp.pi * hull.oswald_efficiency * aspect)
    q = 0.5 * density * speed_sq * hull.lift_area
    drag, lift = q * cd, q * cl
    x = -jnp.cos(alpha) * drag + jnp.sin(alpha) * lift
    z_frd = -jnp.sin(alpha) * drag - jnp.cos(alpha) * lift
    zero = jnp.zeros(())
    return jnp.stack([x, zero, -z_frd, zero, zero, zero])


def crossflow_drag(hull: HullParams, density, nu_r: jnp.ndarray) -> jnp.ndarray:
    """(6,) cross-flow drag wrench about the reference point, body FLU, at relative velocity nu_r (6,)."""
    k = 0.5 * density * hull.crossflow_height * hull.crossflow_drag_coefficient * hull.strip_dx
    x = hull.strip_x
    lateral = nu_r[1] + x * nu_r[5]  # sway velocity of each strip (FLU: v + x r)
    side = -k * lateral * jnp.abs(lateral)
    zero = jnp.zeros(())
    y, n = jnp.sum(side), jnp.sum(x * side)
    if not hull.crossflow_heave:
        return jnp.stack([zero, y, zero, zero, zero, n])
    vertical = nu_r[2] - x * nu_r[4]  # heave velocity of each strip (FLU: w − x q)
    up = -k * vertical * jnp.abs(vertical)
    return jnp.stack([zero, y, jnp.sum(up), zero, -jnp.sum(x * up), n])
