"""Fossen's equations of motion for one rigid body in a fluid, body frame FLU.

    M_RB ν̇ + C_RB(ν)ν + M_A ν̇_r + C_A(ν_r)ν_r + D(ν_r)ν_r + g(η) = τ,    ν_r = ν − ν_c

ν = [v, ω]: body-frame linear (m/s) and angular (rad/s) velocity; wrenches are [force (N),
moment about the centre of gravity (N m)] in the body frame. The body origin is the centre of
gravity, so M_RB = diag(m, m, m, Ix, Iy, Iz). The fluid coefficients are given about the vehicle's
reference point o (`HydroParams.reference_point`, the CG for the ROVs): there the velocity is
ν_o = H ν with H = [[I, S(r)ᵀ], [0, I]] (v_o = v + ω × r), the fluid wrench τ_o is evaluated, and
H ᵀ τ_o is its wrench about the CG; the added mass about the CG is Hᵀ M_A H. M_A is a symmetric
6 × 6 matrix; for the ROVs (diagonal, about the CG) the Coriolis terms are cross products and the
solve a division.

Added mass is solved exactly, not lagged: `hydro_terms` returns the acceleration ν̇ that solves
(M_RB + M_A) ν̇ = everything else, and the wrench which, applied to the rigid body alone,
produces that same ν̇ (τ_applied = τ_other − M_A ν̇). That wrench is what MuJoCo receives in open
water; with contacts the added mass goes into MuJoCo's mass matrix instead and MuJoCo receives
τ_other (`marinejax.physics`).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct

import marinejax.hydro.hull as hull_terms
from marinejax.hydro.params import HydroParams


def skew(x: jnp.ndarray) -> jnp.ndarray:
    """Skew-symmetric matrix S(x) with S(x) y = x × y."""
    z = jnp.zeros_like(x[..., 0])
    return jnp.stack(
        [
            jnp.stack([z, -x[..., 2], x[..., 1]], -1),
            jnp.stack([x[..., 2], z, -x[..., 0]], -1),
            jnp.stack([-x[..., 1], x[..., 0], z], -1),
        ],
        -2,
    )


def rigid_body_mass_diagonal(mass: jnp.ndarray, inertia: jnp.ndarray) -> jnp.ndarray:
    """Diagonal (6,) of M_RB for a body whose origin is its centre of gravity; mass in kg, principal inertia (3,) in kg m^2."""
    return jnp.concatenate([jnp.full((3,), mass), inertia])


def rigid_body_mass_matrix(mass: jnp.ndarray, inertia: jnp.ndarray) -> jnp.ndarray:
    """M_RB (6, 6) for a body whose origin is its centre of gravity."""
    return jnp.diag(rigid_body_mass_diagonal(mass, inertia))


def added_mass_matrix(params: HydroParams) -> jnp.ndarray:
    """M_A (6, 6), symmetric."""
    return params.added_mass_matrix()


def coriolis_matrix(mass_matrix: jnp.ndarray, nu: jnp.ndarray) -> jnp.ndarray:
    """C(ν) (6, 6) of a symmetric mass matrix, Fossen's m2c form (skew-symmetric, so νᵀCν = 0)."""
    m = 0.5 * (mass_matrix + mass_matrix.T)
    a = m[:3, :3] @ nu[:3] + m[:3, 3:] @ nu[3:]
    b = m[3:, :3] @ nu[:3] + m[3:, 3:] @ nu[3:]
    sa, sb = skew(a), skew(b)
    return jnp.block([[jnp.zeros((3, 3)), -sa], [-sa, -sb]])


def coriolis_force_diagonal(mass_diag: jnp.ndarray, nu: jnp.ndarray) -> jnp.ndarray:
    """C(ν)ν (6,) for a diagonal mass matrix diag(mass_diag), without forming C: with a = M11 v,
    b = M22 ω, C(ν)ν = [ω × a, v × a + ω × b]. Equal to coriolis_matrix(diag(mass_diag), ν) @ ν."""
    v, w = nu[:3], nu[3:]
    return _kirchhoff(v, w, mass_diag[:3] * v, mass_diag[3:] * w)


def _kirchhoff(v: jnp.ndarray, w: jnp.ndarray, a: jnp.ndarray, b: jnp.ndarray) -> jnp.ndarray:
    """C(ν)ν = [ω × a, v × a + ω × b] from the momenta [a; b] = M ν (Kirchhoff's form)."""
    return jnp.concatenate([jnp.cross(w, a), jnp.cross(v, a) + jnp.cross(w, b)])


def coriolis_force(mass_matrix: jnp.ndarray, nu: jnp.ndarray) -> jnp.ndarray:
    """C(ν)ν (6,) for a symmetric mass matrix (6, 6), without forming C: with [a; b] = M ν,
    C(ν)ν = [ω × a, v × a + ω × b]. Equal to coriolis_matrix(mass_matrix, ν) @ ν."""
    momenta = mass_matrix @ nu
    return _kirchhoff(nu[:3], nu[3:], momenta[:3], momenta[3:])


def _damping_diagonal(params: HydroParams, nu_r: jnp.ndarray) -> jnp.ndarray:
    return params.linear_damping + params.quadratic_damping * jnp.abs(nu_r)


def damping_matrix(params: HydroParams, nu_r: jnp.ndarray) -> jnp.ndarray:
    """D(ν_r) = D_L + diag(D_Q ⊙ |ν_r|) (6, 6); D(ν_r) ν_r is the drag magnitude (opposes motion)."""
    return jnp.diag(_damping_diagonal(params, nu_r))


def buoyancy_wrench(params: HydroParams, rot: jnp.ndarray, gravity: jnp.ndarray) -> jnp.ndarray:
    """Buoyancy B = ρ g ∇ acting upward at the centre of buoyancy, as a body-frame wrench (6,).

    rot: (3, 3) body-to-world rotation; gravity: scalar magnitude g (m/s^2).
    """
    up_body = rot[2, :]  # world +z expressed in the body frame (Rᵀ e_z)
    force = params.fluid_density * gravity * params.volume * up_body
    return jnp.concatenate([force, jnp.cross(params.center_of_buoyancy, force)])


def current_in_body(rot: jnp.ndarray, current_world: jnp.ndarray, omega: jnp.ndarray):
    """Irrotational current in the body frame: ν_c = [Rᵀ v_c, 0] and its derivative [−ω × Rᵀ v_c, 0].

    current_world: (3,) m/s, world frame, held constant over the step.
    """
    vc = rot.T @ current_world
    zeros = jnp.zeros(3)
    return jnp.concatenate([vc, zeros]), jnp.concatenate([-jnp.cross(omega, vc), zeros])


# C_A entries (row, column) the REMUS reference drops: its surge row and the Munk moments
# (Fossen 2021, section 8.4.2; `HydroParams.munk_terms` False)
_MUNK_ROWS = np.array([4, 0, 4, 2, 5, 0, 5, 1])
_MUNK_COLS = np.array([0, 4, 2, 4, 0, 5, 1, 5])


def transfer_matrix(r: jnp.ndarray) -> jnp.ndarray:
    """H(r) (6, 6): the velocity [v + ω × r, ω] of the point r (m, body frame, from the CG) is H ν."""
    return jnp.eye(6).at[:3, 3:].set(skew(r).T)


def added_mass_at_cg(params: HydroParams) -> jnp.ndarray:
    """M_A about the CG (6, 6): Hᵀ M_A H with H = H(reference_point)."""
    h = transfer_matrix(params.reference_point)
    return h.T @ params.added_mass_matrix() @ h


def fluid_wrench(params: HydroParams, nu_r: jnp.ndarray, nu_c_dot: jnp.ndarray) -> jnp.ndarray:
    """The fluid wrench about the CG (6,), body FLU, buoyancy and the added-mass inertia −M_A ν̇
    excluded: −C_A(ν_r,o) ν_r,o − D(ν_r,o) ν_r,o + M_A ν̇_c and a slender hull's lift, drag and
    cross-flow drag, all evaluated at the reference point o and moved to the CG."""
    r = params.reference_point
    nu_o = jnp.concatenate([nu_r[:3] + jnp.cross(nu_r[3:], r), nu_r[3:]])
    m_a = params.added_mass_matrix()
    if params.munk_terms:
        coriolis = coriolis_force(m_a, nu_o)
    else:
        coriolis = coriolis_matrix(m_a, nu_o).at[_MUNK_ROWS, _MUNK_COLS].set(0.0) @ nu_o
    speed = jnp.sqrt(nu_o[0] ** 2 + nu_o[1] ** 2 + nu_o[2] ** 2)
    damping = (params.linear_damping * jnp.exp(-params.damping_fade * speed) + params.quadratic_damping * jnp.abs(nu_o)) * nu_o
    wrench = -coriolis - damping + m_a @ nu_c_dot  # ν̇_c is the same at every point (irrotational current)
    if params.hull is not None:
        wrench = wrench + hull_terms.lift_drag(params.hull, params.fluid_density, nu_o)
        wrench = wrench + hull_terms.crossflow_drag(params.hull, params.fluid_density, nu_o)
    return jnp.concatenate([wrench[:3], wrench[3:] + jnp.cross(r, wrench[:3])])


@struct.dataclass
class HydroTerms:
    """Result of one evaluation of the equations of motion (body frame FLU)."""

    acceleration: jnp.ndarray  # (6,) ν̇, m/s^2 and rad/s^2
    applied_wrench: jnp.ndarray  # (6,) wrench to apply to the rigid body (N, N m), gravity excluded
    other_wrench: jnp.ndarray  # (6,) τ_other: propulsion, fluid and buoyancy, without −M_A ν̇ and the weight


def hydro_terms(
    params: HydroParams,
    mass: jnp.ndarray,
    inertia: jnp.ndarray,
    rot: jnp.ndarray,
    nu: jnp.ndarray,
    tau: jnp.ndarray,
    current_world: jnp.ndarray,
    gravity: jnp.ndarray,
) -> HydroTerms:
    """Solve the equations of motion for ν̇ and the wrench that reproduces it on the bare rigid body.

    mass (kg), inertia (3,) kg m^2: rigid body; rot: (3, 3) body-to-world; nu: (6,) body velocity;
    tau: (6,) propulsion wrench, body frame; current_world: (3,) m/s; gravity: g (m/s^2), pointing
    along world −z. The weight m g is not part of `applied_wrench`: the rigid-body engine applies it.
    """
    nu_c, nu_c_dot = current_in_body(rot, current_world, nu[3:])
    nu_r = nu - nu_c
    m_rb = rigid_body_mass_diagonal(mass, inertia)
    weight = jnp.concatenate([-mass * gravity * rot[2, :], jnp.zeros(3)])
    if not params.simple:
        fluid = fluid_wrench(params, nu_r, nu_c_dot) + buoyancy_wrench(params, rot, gravity)
        m_a = added_mass_at_cg(params)
        tau_other = tau + fluid
        rhs = tau_other + weight - coriolis_force_diagonal(m_rb, nu)
        acceleration = jnp.linalg.solve(jnp.diag(m_rb) + m_a, rhs)
        return HydroTerms(acceleration=acceleration, applied_wrench=tau_other - m_a @ acceleration, other_wrench=tau_other)
    # M_RB and M_A diagonal (CG at the origin, principal axes; diagonal added mass): the Coriolis
    # terms are cross products and the solve is a division.
    m_a = params.added_mass
    fluid = (
        -coriolis_force_diagonal(m_a, nu_r)
        - _damping_diagonal(params, nu_r) * nu_r
        + buoyancy_wrench(params, rot, gravity)
        + m_a * nu_c_dot
    )
    tau_other = tau + fluid
    rhs = tau_other + weight - coriolis_force_diagonal(m_rb, nu)
    acceleration = rhs / (m_rb + m_a)
    return HydroTerms(acceleration=acceleration, applied_wrench=tau_other - m_a * acceleration, other_wrench=tau_other)


def kinetic_energy(params: HydroParams, mass, inertia, nu_r: jnp.ndarray) -> jnp.ndarray:
    """½ νᵀ M_RB ν + ½ ν_rᵀ M_A ν_r with ν = ν_r (no current), in J."""
    rigid = 0.5 * jnp.sum(rigid_body_mass_diagonal(mass, inertia) * nu_r**2)
    return rigid + 0.5 * nu_r @ (added_mass_at_cg(params) @ nu_r)


def potential_energy(params: HydroParams, mass, position: jnp.ndarray, rot: jnp.ndarray, gravity) -> jnp.ndarray:
    """Gravitational minus buoyant potential (J): m g z_CG − ρ g ∇ z_CB, world z up."""
    z_cb = position[2] + rot[2, :] @ params.center_of_buoyancy
    return mass * gravity * position[2] - params.fluid_density * gravity * params.volume * z_cb
