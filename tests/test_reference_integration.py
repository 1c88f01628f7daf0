"""Independent reference check: marinejax.rollout against a high-accuracy integration of Fossen's equations.

What is compared: a coupled 10 s manoeuvre of the BlueROV2 Heavy (surge, yaw and heave commanded
together, from a 10 degree initial roll, in still water) simulated by `marinejax.rollout` at its
default settings (MuJoCo MJX with the second-order midpoint integrator, float32, one 50 ms physics
step per 50 ms control step) and by a reference written here from scratch in NumPy and integrated
with SciPy's DOP853 at rtol = atol = 1e-10:

    (M_RB + M_A) ν̇ = τ + g_B(η) + g_W(η) − C_RB(ν) ν − C_A(ν) ν − D(ν) ν        (Fossen 2021)
    ṗ = R(q) v,   q̇ = ½ q ⊗ (0, ω)

Why it is independent: the reference imports nothing from marinejax's physics or hydrodynamics (no
shared rotation, Coriolis, damping or restoring code), takes its parameters as literals from the
paper, and integrates all of the rigid-body dynamics itself, whereas the simulator leaves the
rigid-body part (including the rigid-body Coriolis terms and gravity) to MuJoCo and only injects the
fluid wrench. Agreement therefore checks frames, signs, the added-mass treatment, the hand-off to
MuJoCo and the time integration together. The remaining difference is the simulator's
second-order time discretisation and float32 arithmetic, which the tolerances (3 mm, 0.3 degree)
allow for. The convergence test halves the step twice and checks the error falls about 4x each time
(2x for the first-order "euler" integrator kept for comparison).
"""

import math
import time

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import marinejax

# ---------------------------------------------------------------------------------------------
# BlueROV2 Heavy, von Benzon et al. 2022, J. Mar. Sci. Eng. 10(12):1898 (already in body FLU).
MASS = 13.5  # kg
INERTIA = np.array([0.26, 0.23, 0.37])  # kg m^2, principal, about the CG
GRAVITY = 9.81  # m/s^2
RHO = 1000.0  # kg/m^3
VOLUME = 0.0134  # m^3
R_CB = np.array([0.0, 0.0, 0.01])  # m, centre of buoyancy in body FLU (1 cm above the CG)
ADDED_MASS = np.array([6.36, 7.12, 18.68, 0.189, 0.135, 0.222])
D_LIN = np.array([13.7, 0.0, 33.0, 0.0, 0.8, 0.0])
D_QUAD = np.array([141.0, 217.0, 190.0, 1.19, 0.47, 1.5])

# Manoeuvre: 10 s of 50 ms control steps (the default), each one physics step (the default).
CONTROL_DT = 0.05
SUBSTEPS = 1
STEPS = 200
ROLL0 = math.radians(10.0)

POSITION_TOL = 0.003  # m
ATTITUDE_TOL = math.radians(0.3)  # rad


def command_profile() -> np.ndarray:
    """(STEPS, 6) body wrench [Fx, Fy, Fz, Mx, My, Mz], command k held over [k, k+1) * CONTROL_DT."""
    k = np.arange(STEPS)  # integer indices: switch times fall exactly on control step boundaries
    per_s = round(1.0 / CONTROL_DT)
    cmd = np.zeros((STEPS, 6))
    cmd[:, 0] = np.where(k < 6 * per_s, 25.0, 10.0)  # surge: 25 N for 6 s, then 10 N
    cmd[:, 2] = np.where((k >= 1 * per_s) & (k < 8 * per_s), -15.0, 0.0)  # heave down 15 N between 1 s and 8 s
    cmd[:, 5] = np.where((k >= 2 * per_s) & (k < 7 * per_s), 2.0, 0.0)  # yaw 2 N m between 2 s and 7 s
    return cmd


# ---------------------------------------------------------------------------------------------
# Reference model (NumPy, float64).


def skew(x):
    """S(x) with S(x) y = x × y."""
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def m2c(m6, nu):
    """Fossen's m2c: Coriolis-centripetal matrix C(ν) (6, 6) of a symmetric mass matrix."""
    a = m6[:3, :3] @ nu[:3] + m6[:3, 3:] @ nu[3:]
    b = m6[3:, :3] @ nu[:3] + m6[3:, 3:] @ nu[3:]
    c = np.zeros((6, 6))
    c[:3, 3:] = -skew(a)
    c[3:, :3] = -skew(a)
    c[3:, 3:] = -skew(b)
    return c


def quat_rotation(q):
    """Rotation matrix body → world of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


def quat_multiply(p, q):
    """Hamilton product p ⊗ q, scalar first."""
    pw, pv = p[0], p[1:]
    qw, qv = q[0], q[1:]
    return np.concatenate([[pw * qw - pv @ qv], pw * qv + qw * pv + np.cross(pv, qv)])


M_RB = np.diag(np.concatenate([np.full(3, MASS), INERTIA]))
M_A = np.diag(ADDED_MASS)


def transported(m_a_diagonal, r):
    """A diagonal added-mass matrix given about the point r (m, body FLU, from the CG), expressed
    about the CG: Hᵀ M H with H = [[I, S(r)ᵀ], [0, I]] (Fossen 2021, section 3.3), since the
    velocity of that point is v + ω × r. A full symmetric matrix with translation–rotation couplings."""
    h = np.eye(6)
    h[:3, 3:] = skew(r).T
    return h.T @ np.diag(m_a_diagonal) @ h


# The Heavy's added mass as if it were diagonal about a point 5 cm forward and 8 cm above the CG
# (couplings up to 0.93 kg m: heave-pitch, surge-pitch, sway-roll and sway-yaw): the full-matrix case.
M_A_COUPLED = transported(ADDED_MASS, np.array([0.05, 0.0, 0.08]))


def reference_rhs(_t, x, tau, m_a=M_A):
    """x = [p (3, world), q (4, wxyz), v (3, body), ω (3, body)]."""
    q = x[3:7] / np.linalg.norm(x[3:7])
    nu = x[7:13]
    rot = quat_rotation(q)
    weight_body = rot.T @ np.array([0.0, 0.0, -MASS * GRAVITY])  # at the CG: no moment
    buoy_body = rot.T @ np.array([0.0, 0.0, RHO * GRAVITY * VOLUME])
    restoring = np.concatenate([weight_body + buoy_body, np.cross(R_CB, buoy_body)])
    damping = np.diag(D_LIN + D_QUAD * np.abs(nu))
    rhs = tau + restoring - m2c(M_RB, nu) @ nu - m2c(m_a, nu) @ nu - damping @ nu
    nu_dot = np.linalg.solve(M_RB + m_a, rhs)
    p_dot = rot @ nu[:3]
    q_dot = 0.5 * quat_multiply(x[3:7], np.concatenate([[0.0], nu[3:]]))
    return np.concatenate([p_dot, q_dot, nu_dot])


def reference_trajectory(commands, q0, m_a=M_A):
    """States (STEPS, 13) at the end of each control step, one DOP853 solve per zero-order-hold interval
    (added-mass matrix m_a, 6 x 6)."""
    x = np.concatenate([np.zeros(3), q0, np.zeros(6)])
    out = np.empty((len(commands), 13))
    for k, tau in enumerate(commands):
        sol = solve_ivp(
            reference_rhs,
            (k * CONTROL_DT, (k + 1) * CONTROL_DT),
            x,
            method="DOP853",
            rtol=1e-10,
            atol=1e-10,
            args=(tau, m_a),
        )
        assert sol.success, sol.message
        x = sol.y[:, -1].copy()
        x[3:7] /= np.linalg.norm(x[3:7])
        out[k] = x
    return out


# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def vehicle():
    return marinejax.load_vehicle("bluerov2_heavy")


def simulate(vehicle, commands, q0, substeps=SUBSTEPS, integrator=None):
    """marinejax.rollout of the manoeuvre (defaults unless `integrator` is given) as float64 arrays."""
    extra = {} if integrator is None else {"integrator": integrator}
    traj = marinejax.rollout(
        vehicle,
        commands,
        initial=marinejax.initial_state(vehicle, quaternion=q0),
        control_dt=CONTROL_DT,
        substeps=substeps,
        mode="wrench",
        **extra,
    )
    return {
        "time": np.asarray(traj.time, dtype=float),
        "position": np.asarray(traj.position, dtype=float),
        "quaternion": np.asarray(traj.quaternion, dtype=float),
        "velocity": np.asarray(traj.velocity, dtype=float),
        "angular_velocity": np.asarray(traj.angular_velocity, dtype=float),
    }


@pytest.fixture(scope="module")
def runs(vehicle):
    """Simulator and reference trajectories of the manoeuvre (computed once for the module)."""
    commands = command_profile()
    q0 = np.array([math.cos(ROLL0 / 2), math.sin(ROLL0 / 2), 0.0, 0.0])
    t0 = time.perf_counter()
    sim = simulate(vehicle, commands, q0)
    t1 = time.perf_counter()
    ref = reference_trajectory(commands, q0)
    t2 = time.perf_counter()
    print(f"\nsimulator rollout {t1 - t0:.1f} s (incl. compile), reference {t2 - t1:.1f} s")
    return sim, ref


def quaternion_angle(q1, q2):
    """Rotation angle (rad) between rows of unit quaternions, sign-insensitive."""
    q1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    q2 = q2 / np.linalg.norm(q2, axis=-1, keepdims=True)
    dot = np.clip(np.abs(np.sum(q1 * q2, axis=-1)), 0.0, 1.0)
    return 2.0 * np.arccos(dot)


def yaw_of(q):
    """Heading (rad) of rows of quaternions (w, x, y, z): angle of the body x axis in the world xy plane."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def roll_of(q):
    """Roll (rad) of rows of quaternions (w, x, y, z), ZYX Euler convention."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))


def test_parameters_match_loaded_vehicle(vehicle):
    h = vehicle.sys.hydro
    np.testing.assert_allclose(np.asarray(h.added_mass), ADDED_MASS, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(h.linear_damping), D_LIN, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(h.quadratic_damping), D_QUAD, rtol=1e-6)
    np.testing.assert_allclose(float(h.volume), VOLUME, rtol=1e-6)
    np.testing.assert_allclose(float(h.fluid_density), RHO, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(h.center_of_buoyancy), R_CB, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(float(vehicle.sys.model.body_mass[1]), MASS, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(vehicle.sys.model.body_inertia[1]), INERTIA, rtol=1e-6)
    np.testing.assert_allclose(-float(vehicle.sys.model.opt.gravity[2]), GRAVITY, rtol=1e-6)


def test_manoeuvre_is_nontrivial(runs):
    _, ref = runs
    pos, quat = ref[:, :3], ref[:, 3:7]
    travelled = np.sum(np.linalg.norm(np.diff(np.vstack([np.zeros(3), pos]), axis=0), axis=1))
    yawed = np.max(np.abs(np.unwrap(np.concatenate([[0.0], yaw_of(quat)]))))
    depth_change = -np.min(pos[:, 2])
    speed = np.linalg.norm(ref[:, 7:10], axis=1)
    print(f"\ntravelled {travelled:.2f} m, yawed {math.degrees(yawed):.0f} deg, "
          f"dived {depth_change:.2f} m, max speed {speed.max():.2f} m/s")
    assert travelled > 1.0
    assert yawed > math.radians(30.0)
    assert depth_change > 0.2
    assert 0.3 < speed.max() < 0.6  # moderate speed, as intended
    # Roll restoring moment exercised: the 10 degree initial roll swings back through level within the
    # first second (only surge is commanded then).
    roll = roll_of(quat)
    assert roll[0] > math.radians(9.0)
    assert np.min(roll[: round(1.0 / CONTROL_DT)]) < math.radians(1.0)


def test_simulator_matches_reference(runs):
    sim, ref = runs
    np.testing.assert_allclose(sim["time"], CONTROL_DT * np.arange(1, STEPS + 1), rtol=1e-6)
    pos_err = np.linalg.norm(sim["position"] - ref[:, :3], axis=1)
    att_err = quaternion_angle(sim["quaternion"], ref[:, 3:7])
    vel_err = np.linalg.norm(sim["velocity"] - ref[:, 7:10], axis=1)
    rate_err = np.linalg.norm(sim["angular_velocity"] - ref[:, 10:13], axis=1)
    kp, ka = int(np.argmax(pos_err)), int(np.argmax(att_err))
    print(
        f"\nmax position error {pos_err.max() * 1000:.2f} mm (t = {sim['time'][kp]:.2f} s), "
        f"max attitude error {math.degrees(att_err.max()):.3f} deg (t = {sim['time'][ka]:.2f} s), "
        f"max velocity error {vel_err.max() * 1000:.2f} mm/s, "
        f"max angular-rate error {math.degrees(rate_err.max()):.3f} deg/s"
    )
    assert pos_err.max() < POSITION_TOL, f"position error {pos_err.max():.4f} m at t = {sim['time'][kp]:.2f} s"
    assert att_err.max() < ATTITUDE_TOL, (
        f"attitude error {math.degrees(att_err.max()):.3f} deg at t = {sim['time'][ka]:.2f} s"
    )


def test_bounds_detect_a_small_model_error(runs):
    """The tolerances are tight relative to the manoeuvre: a reference whose yaw moment is 5 % too
    large already departs from the true reference by more than both bounds."""
    _, ref = runs
    commands = command_profile()
    commands[:, 5] *= 1.05
    q0 = np.array([math.cos(ROLL0 / 2), math.sin(ROLL0 / 2), 0.0, 0.0])
    perturbed = reference_trajectory(commands, q0)
    assert np.linalg.norm(perturbed[:, :3] - ref[:, :3], axis=1).max() > POSITION_TOL
    assert quaternion_angle(perturbed[:, 3:7], ref[:, 3:7]).max() > ATTITUDE_TOL


@pytest.mark.parametrize("integrator, order", [("midpoint", 2), ("euler", 1)])
def test_convergence_order(vehicle, runs, integrator, order):
    """Halving the physics step divides the position error by about 2^order (50 → 25 → 12.5 ms for
    midpoint; 10 → 5 → 2.5 ms for euler, which is unstable beyond 20 ms)."""
    _, ref = runs
    commands = command_profile()
    q0 = np.array([math.cos(ROLL0 / 2), math.sin(ROLL0 / 2), 0.0, 0.0])
    first = 1 if integrator == "midpoint" else 5
    errors = []
    for substeps in (first, 2 * first, 4 * first):
        sim = simulate(vehicle, commands, q0, substeps=substeps, integrator=integrator)
        errors.append(np.linalg.norm(sim["position"] - ref[:, :3], axis=1).max())
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    print(f"\n{integrator}: max position errors {[f'{e * 1000:.3f} mm' for e in errors]}, ratios {ratios[0]:.2f}, {ratios[1]:.2f}")
    for r in ratios:
        assert 2**order * 0.75 < r < 2**order * 1.25


@pytest.fixture(scope="module")
def coupled_vehicle(tmp_path_factory):
    """The Heavy with M_A_COUPLED: its file gives all 36 added-mass values instead of 6."""
    from marinejax.vehicle import model_dir

    text = (model_dir() / "bluerov2_heavy.xml").read_text()
    old = '<numeric name="marinejax:vonbenzon2022:added_mass" data="6.36 7.12 18.68 0.189 0.135 0.222"/>'
    assert old in text
    values = " ".join(f"{v:.9g}" for v in M_A_COUPLED.reshape(-1))
    path = tmp_path_factory.mktemp("vehicles") / "coupled_heavy.xml"
    path.write_text(text.replace(old, f'<numeric name="marinejax:vonbenzon2022:added_mass" data="{values}"/>'))
    return marinejax.load_vehicle(str(path))


def test_full_added_mass_matrix_matches_the_reference(coupled_vehicle, runs):
    """A vehicle with a full (non-diagonal) added-mass matrix against the reference integrated with
    the same matrix, on the same manoeuvre and with the same bounds; the couplings matter: the
    diagonal model's trajectory departs from this one by more than the bounds."""
    h = coupled_vehicle.sys.hydro
    assert not h.simple and np.abs(M_A_COUPLED - np.diag(np.diag(M_A_COUPLED))).max() > 0.9  # kg m
    np.testing.assert_allclose(np.asarray(h.added_mass_matrix()), M_A_COUPLED, rtol=1e-6, atol=1e-6)
    commands = command_profile()
    q0 = np.array([math.cos(ROLL0 / 2), math.sin(ROLL0 / 2), 0.0, 0.0])
    sim = simulate(coupled_vehicle, commands, q0)
    ref = reference_trajectory(commands, q0, M_A_COUPLED)
    pos_err = np.linalg.norm(sim["position"] - ref[:, :3], axis=1).max()
    att_err = quaternion_angle(sim["quaternion"], ref[:, 3:7]).max()
    print(f"\nfull added mass: max position error {pos_err * 1000:.2f} mm, max attitude error {math.degrees(att_err):.3f} deg")
    assert pos_err < POSITION_TOL and att_err < ATTITUDE_TOL
    _, diagonal = runs
    assert np.linalg.norm(diagonal[:, :3] - ref[:, :3], axis=1).max() > 3 * POSITION_TOL
    assert quaternion_angle(diagonal[:, 3:7], ref[:, 3:7]).max() > 3 * ATTITUDE_TOL
