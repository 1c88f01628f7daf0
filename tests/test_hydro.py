"""Properties of the pure hydrodynamics functions (Fossen 2021, ch. 3 and 6)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.frames import quat_from_euler, quat_to_mat
from marinejax.hydro import (
    HydroParams,
    added_mass_matrix,
    buoyancy_wrench,
    coriolis_matrix,
    hydro_terms,
    rigid_body_mass_matrix,
    skew,
)


@pytest.fixture(scope="module", params=["vonbenzon2022", "wu2018"])
def vehicle(request):
    return mj.load_vehicle("bluerov2_heavy", param_set=request.param)


def mass_matrices(v):
    m_rb = rigid_body_mass_matrix(v.sys.model.body_mass[1], v.sys.model.body_inertia[1])
    return m_rb, added_mass_matrix(v.sys.hydro)


def test_skew_is_the_cross_product():
    x, y = jnp.array([0.3, -1.2, 2.0]), jnp.array([1.5, 0.2, -0.7])
    np.testing.assert_allclose(skew(x) @ y, jnp.cross(x, y), rtol=1e-6)


def test_mass_matrices_are_symmetric_positive_definite(vehicle):
    for m in mass_matrices(vehicle):
        m = np.asarray(m, dtype=np.float64)
        np.testing.assert_array_equal(m, m.T)
        assert np.linalg.eigvalsh(m).min() > 0


def test_coriolis_does_no_work(vehicle):
    nus = jax.random.normal(jax.random.PRNGKey(0), (100, 6))
    for m in mass_matrices(vehicle):
        power = jax.vmap(lambda nu: nu @ coriolis_matrix(m, nu) @ nu)(nus)
        scale = jax.vmap(lambda nu: jnp.abs(nu) @ jnp.abs(coriolis_matrix(m, nu)) @ jnp.abs(nu))(nus)
        assert float(jnp.max(jnp.abs(power) / scale)) < 1e-6
        # and C is skew-symmetric, the stronger property
        c = coriolis_matrix(m, nus[0])
        np.testing.assert_allclose(c, -c.T, atol=1e-6)


def test_rigid_body_coriolis_is_the_transport_term(vehicle):
    """C_RB(ν)ν = [m ω × v, ω × I ω] for a body whose origin is its CG."""
    m, inertia = vehicle.sys.model.body_mass[1], vehicle.sys.model.body_inertia[1]
    nu = jnp.array([0.4, -0.2, 0.1, 0.3, -0.5, 0.2])
    v, w = nu[:3], nu[3:]
    expected = jnp.concatenate([m * jnp.cross(w, v), jnp.cross(w, inertia * w)])
    np.testing.assert_allclose(coriolis_matrix(rigid_body_mass_matrix(m, inertia), nu) @ nu, expected, rtol=1e-5, atol=1e-7)


def test_munk_moment_sign(vehicle):
    """C_A(ν)ν for surge u and heave w: pitch moment (Zẇ - Xu̇) u w destabilises (FLU, Fossen 6.4)."""
    h = vehicle.sys.hydro
    u, w = 0.5, 0.1
    nu = jnp.array([u, 0, w, 0, 0, 0])
    moment = -(coriolis_matrix(added_mass_matrix(h), nu) @ nu)[4]  # applied pitch moment
    # -C_A ν ν has moment part a × v... = -(v × a) with a = (Xu̇ u, 0, Zẇ w): pitch (Zẇ - Xu̇) u w
    expected = (h.added_mass[2] - h.added_mass[0]) * u * w
    assert float(moment) == pytest.approx(float(expected), rel=1e-5)


def test_buoyancy_restores_roll(vehicle):
    rot = quat_to_mat(quat_from_euler(0.3, 0.0, 0.0))
    w = buoyancy_wrench(vehicle.sys.hydro, rot, 9.81)
    assert float(w[2]) > 0  # buoyancy points up, mostly along body +z at 0.3 rad of roll
    assert float(w[3]) < 0  # rolled +0.3 rad about x (port side up): the moment rolls it back


def test_hydro_terms_solve_the_full_equation(vehicle):
    """(M_RB + M_A) ν̇ + C_RB ν + C_A ν_r ν_r + D ν_r - buoyancy - weight - M_A ν̇_c = τ, with a current,
    and the applied wrench gives the rigid body alone the same acceleration."""
    h = vehicle.sys.hydro
    m, inertia = vehicle.sys.model.body_mass[1], vehicle.sys.model.body_inertia[1]
    rot = quat_to_mat(quat_from_euler(0.2, -0.1, 0.7))
    nu = jnp.array([0.4, -0.2, 0.1, 0.3, -0.5, 0.2])
    tau = jnp.array([10.0, -4.0, 6.0, 0.5, -0.3, 1.0])
    current = jnp.array([0.2, -0.1, 0.05])
    terms = hydro_terms(h, m, inertia, rot, nu, tau, current, 9.81)
    m_rb, m_a = mass_matrices(vehicle)
    vc = rot.T @ current
    nu_r = nu - jnp.concatenate([vc, jnp.zeros(3)])
    nu_c_dot = jnp.concatenate([-jnp.cross(nu[3:], vc), jnp.zeros(3)])
    damping = (h.linear_damping + h.quadratic_damping * jnp.abs(nu_r)) * nu_r
    weight = jnp.concatenate([rot.T @ jnp.array([0, 0, -m * 9.81]), jnp.zeros(3)])
    lhs = (
        m_rb @ terms.acceleration
        + coriolis_matrix(m_rb, nu) @ nu
        + m_a @ (terms.acceleration - nu_c_dot)
        + coriolis_matrix(m_a, nu_r) @ nu_r
        + damping
        - buoyancy_wrench(h, rot, 9.81)
        - weight
    )
    np.testing.assert_allclose(lhs, tau, atol=2e-5)
    rigid_only = jnp.linalg.solve(m_rb, terms.applied_wrench + weight - coriolis_matrix(m_rb, nu) @ nu)
    np.testing.assert_allclose(rigid_only, terms.acceleration, atol=2e-6)


@pytest.mark.parametrize(
    "field,value,message",
    [
        ("added_mass", [1, 2, 3, 4, 5, float("nan")], "non-finite"),
        ("linear_damping", [1, -2, 3, 4, 5, 6], "must be >= 0"),
        ("volume", 0.0, "must be > 0"),
        ("center_of_buoyancy", [0, 0], "needs 3"),
    ],
)
def test_invalid_parameters_are_rejected_by_name(vehicle, field, value, message):
    with pytest.raises(ValueError, match=f"'{field}'.*{message}|{message}.*{field}|'{field}' {message}"):
        vehicle.sys.hydro.replace_values(**{field: value})


def test_unknown_parameter_field_is_rejected():
    good = mj.load_vehicle("bluerov2_heavy").sys.hydro
    values = {k: np.asarray(getattr(good, k)) for k in ("added_mass", "linear_damping", "quadratic_damping", "volume", "fluid_density", "center_of_buoyancy")}
    with pytest.raises(ValueError, match=r"unknown hydrodynamic field\(s\) \['added_mas'\]"):
        HydroParams.from_mapping({**values, "added_mas": 1.0})


def test_diagonal_coriolis_force_equals_the_m2c_matrix_form(vehicle):
    from marinejax.hydro import coriolis_force_diagonal

    nus = jax.random.normal(jax.random.PRNGKey(1), (20, 6))
    for m in mass_matrices(vehicle):
        fast = jax.vmap(lambda nu: coriolis_force_diagonal(jnp.diagonal(m), nu))(nus)
        full = jax.vmap(lambda nu: coriolis_matrix(m, nu) @ nu)(nus)
        np.testing.assert_allclose(fast, full, rtol=1e-5, atol=1e-5)  # float32 round-off on terms of ~3
