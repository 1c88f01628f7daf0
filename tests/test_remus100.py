"""The REMUS 100 torpedo AUV (models/mjcf/remus100.xml) against its published reference model.

Three kinds of check:
1. Its parameters, recomputed here from the published formulas (Fossen 2021, section 8.4.2: the
   spheroid's mass and inertia, Lamb's k-factors, the damping from the natural frequencies, the hull's
   drag coefficient from Allen et al. 2000's Cd = 0.42).
2. Figures of the reference implementation, the Marine Systems Simulator's `remus100` (Python Vehicle
   Simulator, github cybergalactic/PythonVehicleSimulator, commit c717e07, MIT), run unmodified on its
   own dynamics function with SciPy DOP853 at rtol 1e-9 (2026-12-01): terminal speed, bollard thrust,
   turning circle, stern-plane response, roll period. REFERENCE below.
3. An independent integration: Fossen's REMUS 100 equations written here in NumPy as published (NED
   world, FRD body at the centre of buoyancy, Euler-free quaternion kinematics; nothing shared with
   marinejax, whose body frame is FLU at the CG) integrated by DOP853 at rtol 1e-10, against
   `marinejax.rollout` at its default step (one 50 ms midpoint step per control step, float32) on a
   coupled manoeuvre: rudder, stern planes and propeller changes together.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import marinejax as mj
from marinejax.errors import UserError
from marinejax.frames import quat_to_mat
from marinejax.validation import FOUR_FIN_REFERENCE, REMUS100_REFERENCE, torpedo_manoeuvres

# --- the published model, from its formulas ------------------------------------------------------
L, DIAM, RHO, G = 1.6, 0.19, 1026.0, 9.81
A_SEMI, B_SEMI = L / 2, DIAM / 2
MASS = 4 / 3 * math.pi * RHO * A_SEMI * B_SEMI**2
IX, IY = 2 / 5 * MASS * B_SEMI**2, 1 / 5 * MASS * (A_SEMI**2 + B_SEMI**2)
ZG = 0.02  # m, CG below the CB (FRD z)
ECC = math.sqrt(1 - (B_SEMI / A_SEMI) ** 2)
_LOG = math.log((1 + ECC) / (1 - ECC))
ALPHA0 = 2 * (1 - ECC**2) / ECC**3 * (0.5 * _LOG - ECC)
BETA0 = 1 / ECC**2 - (1 - ECC**2) / (2 * ECC**3) * _LOG
K1, K2 = ALPHA0 / (2 - ALPHA0), BETA0 / (2 - BETA0)
KP = ECC**4 * (BETA0 - ALPHA0) / ((2 - ECC**2) * (2 * ECC**2 - (2 - ECC**2) * (BETA0 - ALPHA0)))
ADDED = np.array([MASS * K1, MASS * K2, MASS * K2, 0.3 * IX, KP * IY, KP * IY])  # about the CB


def skew(x):
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def transfer(r):
    h = np.eye(6)
    h[:3, 3:] = skew(r).T
    return h


M_RB = transfer(np.array([0, 0, ZG])).T @ np.diag([MASS, MASS, MASS, IX, IY, IY]) @ transfer(np.array([0, 0, ZG]))
M_TOTAL = M_RB + np.diag(ADDED)
W_BG = MASS * G * ZG
W_ROLL, W_PITCH = math.sqrt(W_BG / M_TOTAL[3, 3]), math.sqrt(W_BG / M_TOTAL[4, 4])
D_LINEAR = np.array([M_TOTAL[0, 0] / 20, M_TOTAL[1, 1] / 20, M_TOTAL[2, 2] / 20, 2 * 0.3 * W_ROLL * M_TOTAL[3, 3],
                     2 * 0.8 * W_PITCH * M_TOTAL[4, 4], M_TOTAL[5, 5] / 1])
S_HULL = 0.7 * L * DIAM
CD0 = 0.42 * math.pi * B_SEMI**2 / S_HULL
CD_2D = 1.1977288343558283  # Hoerner's curve at B/2T = 0.5, interpolated as the reference does
FIN = {"rudder": 0.5 * RHO * 2 * 0.00665 * 0.5, "stern": 0.5 * RHO * 2 * 0.00665 * 0.7}  # ½ρAC_L, N s²/m²
X_FIN = -L / 2
PROP_D, KT0, KQ0, KT_MAX, KQ_MAX, J_MAX = 0.14, 0.4566, 0.0700, 0.1798, 0.0312, 0.6632
MAX_FIN, MAX_RPM = math.radians(15.0), 1525.0

# --- the reference implementation's figures (module docstring) -------------------------------------
# and marinejax.validation.REMUS100_REFERENCE (the manoeuvres, also printed by `marinejax validate`)
BOLLARD_FORCE = 104.6345  # N, (1 - t) ρ D⁴ K_T0 n² at 1525 rpm


def controls(rudder_deg, stern_deg, rpm):
    """marinejax's normalised actions [rudder, stern planes, propeller] for physical settings."""
    return np.array([math.radians(rudder_deg) / MAX_FIN, math.radians(stern_deg) / MAX_FIN, 2 * rpm / MAX_RPM - 1], np.float32)


@pytest.fixture(scope="module")
def remus():
    return mj.load_vehicle("remus100")


def test_parameters_are_the_published_formulas(remus):
    h = remus.sys.hydro
    np.testing.assert_allclose(float(remus.sys.model.body_mass[1]), MASS, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(remus.sys.model.body_inertia[1]), [IX, IY, IY], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(h.added_mass), ADDED, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(h.linear_damping), D_LINEAR, rtol=1e-6)
    np.testing.assert_allclose(float(h.fluid_density * h.volume), MASS, rtol=1e-6)  # neutrally buoyant
    np.testing.assert_allclose(np.asarray(h.reference_point), [0, 0, ZG], atol=1e-9)
    np.testing.assert_allclose(np.asarray(h.center_of_buoyancy), [0, 0, ZG], atol=1e-9)
    np.testing.assert_allclose([float(h.hull.lift_area), float(h.hull.drag_coefficient)], [S_HULL, CD0], rtol=1e-6)
    assert not h.munk_terms and not h.hull.crossflow_heave and h.hull.strip_x.shape == (21,)
    # the values the reference code computes (printed from it)
    np.testing.assert_allclose([K1, K2, KP], [0.027035940, 0.948701904, 0.850647057], rtol=1e-7)


def test_bollard_thrust_is_the_open_water_coefficient_at_zero_advance(remus):
    """At rest with the shaft at 1525 rpm: (1 − t) ρ D⁴ K_T(0) n² along +x and a tenth of ρ D⁵ K_Q(0) n² in roll."""
    prop = remus.sys.actuators[2]
    n = MAX_RPM / 60
    wrench = np.asarray(prop.kind.wrench(prop.design, prop.params, np.array([MAX_RPM], np.float32), np.zeros(6, np.float32)))
    np.testing.assert_allclose(wrench[0], 0.9 * RHO * PROP_D**4 * KT0 * n**2, rtol=1e-5)
    np.testing.assert_allclose(wrench[0], BOLLARD_FORCE, rtol=1e-5)
    np.testing.assert_allclose(wrench[3], 0.1 * RHO * PROP_D**5 * KQ0 * n**2, rtol=1e-5)
    np.testing.assert_allclose(wrench[4], 0.02 * wrench[0], rtol=1e-5)  # thrust line 2 cm above the CG: nose down
    np.testing.assert_allclose(wrench[[1, 2, 5]], 0.0, atol=1e-6)


@pytest.fixture(scope="module")
def manoeuvres(remus):
    return torpedo_manoeuvres(remus)


@pytest.mark.parametrize("quantity, tolerance", [
    ("terminal speed, 1525 rpm", 1e-3), ("turning diameter, rudder 15°", 5e-3), ("turn rate, rudder 15°", 5e-3),
    ("heel into the turn, rudder 15°", 0.02), ("pitch after 5 s of stern planes 10°", 0.01),
    ("depth gained in those 5 s", 0.02), ("roll period, free decay from 10°", 0.01),
])
def test_manoeuvres_reproduce_the_reference_implementation(manoeuvres, quantity, tolerance):
    """Relative tolerances: 0.1 % on speed, 0.5 % on the turning circle, 1-2 % on the transients."""
    reference, _ = REMUS100_REFERENCE[quantity]
    assert manoeuvres[quantity] == pytest.approx(reference, rel=tolerance)


def test_fins_turn_and_dive_the_documented_way(manoeuvres):
    """A positive rudder turns to starboard (heading rate > 0 in FRD), positive stern planes pitch the
    nose down and the vehicle dives, the heel is into the turn (starboard down)."""
    assert manoeuvres["turn rate, rudder 15°"] > 5 and manoeuvres["heel into the turn, rudder 15°"] > 1
    assert manoeuvres["pitch after 5 s of stern planes 10°"] < -30 and manoeuvres["depth gained in those 5 s"] > 3


def test_roll_period_matches_the_restoring_moment_and_the_inertia(manoeuvres):
    """The damped period of roll coupled to the nearly free sway: ω_n² = W·BG / (M44 − M24²/M22),
    ζ = D44 / (2 ω_n (M44 − M24²/M22)), with M the rigid-body plus added mass at the CB."""
    inertia = M_TOTAL[3, 3] - M_TOTAL[1, 3] ** 2 / M_TOTAL[1, 1]
    w_n = math.sqrt(W_BG / inertia)
    zeta = D_LINEAR[3] / (2 * w_n * inertia)
    closed = 2 * math.pi / (w_n * math.sqrt(1 - zeta**2))
    assert manoeuvres["roll period, free decay from 10°"] == pytest.approx(closed, rel=0.01)


def test_neutral_vehicle_at_rest_stays_at_rest(remus):
    traj = mj.rollout(remus, np.tile(controls(0, 0, 0), (200, 1)))
    assert float(np.abs(traj.position).max()) < 1e-5 and float(np.abs(traj.velocity).max()) < 1e-5


def steady_start(remus, rpm):
    """The state after 60 s straight at `rpm` (settled)."""
    traj = mj.rollout(remus, np.tile(controls(0, 0, rpm), (1200, 1)))
    return mj.initial_state(remus, quaternion=traj.quaternion[-1], velocity=traj.velocity[-1],
                            angular_velocity=traj.angular_velocity[-1], actuators=traj.actuators[-1])


# --- independent integration -------------------------------------------------------------------
def reference_rhs(_t, x, command):
    """Fossen's REMUS 100 at the CB, NED/FRD: x = [p (3), q (4, w x y z, body → NED), ν (6), δ_r, δ_s, n (rpm)]."""
    q = x[3:7] / np.linalg.norm(x[3:7])
    w0, x0, y0, z0 = q
    rot = np.array([[1 - 2 * (y0 * y0 + z0 * z0), 2 * (x0 * y0 - w0 * z0), 2 * (x0 * z0 + w0 * y0)],
                    [2 * (x0 * y0 + w0 * z0), 1 - 2 * (x0 * x0 + z0 * z0), 2 * (y0 * z0 - w0 * x0)],
                    [2 * (x0 * z0 - w0 * y0), 2 * (y0 * z0 + w0 * x0), 1 - 2 * (x0 * x0 + y0 * y0)]])
    nu = x[7:13]
    u, v, w, p, qq, r = nu
    d_r, d_s, rpm = x[13:16]
    speed = math.sqrt(u * u + v * v + w * w)

    def coriolis(m, nu):
        a = m[:3, :3] @ nu[:3] + m[:3, 3:] @ nu[3:]
        b = m[3:, :3] @ nu[:3] + m[3:, 3:] @ nu[3:]
        c = np.zeros((6, 6))
        c[:3, 3:], c[3:, :3], c[3:, 3:] = -skew(a), -skew(a), -skew(b)
        return c

    c_a = coriolis(np.diag(ADDED), nu)
    for i, j in ((4, 0), (0, 4), (4, 2), (2, 4), (5, 0), (0, 5), (5, 1), (1, 5)):
        c_a[i, j] = 0.0
    damping = D_LINEAR * np.array([math.exp(-3 * speed), math.exp(-3 * speed), 1, 1, 1, 1]) * nu
    # hull lift and drag, vertical plane, at the CB
    alpha = math.atan2(w, u)
    aspect = DIAM**2 / S_HULL
    cl = math.pi * aspect / (1 + math.sqrt(1 + (aspect / 2) ** 2)) * alpha
    cd = CD0 + cl**2 / (math.pi * 0.7 * aspect)
    f_d, f_l = 0.5 * RHO * speed**2 * S_HULL * cd, 0.5 * RHO * speed**2 * S_HULL * cl
    lift = np.array([-math.cos(alpha) * f_d + math.sin(alpha) * f_l, 0, -math.sin(alpha) * f_d - math.cos(alpha) * f_l, 0, 0, 0])
    # cross-flow drag, sway and yaw, the reference's 21 strips
    cross = np.zeros(6)
    for xs in np.linspace(-L / 2, L / 2, 21):
        flow = (v + xs * r) * abs(v + xs * r)
        cross[1] -= 0.5 * RHO * DIAM * CD_2D * flow * (L / 20)
        cross[5] -= 0.5 * RHO * DIAM * CD_2D * xs * flow * (L / 20)
    # restoring: weight at the CG, buoyancy at the CB (W = B)
    f_w = rot.T @ np.array([0, 0, MASS * G])
    restoring = np.concatenate([f_w - rot.T @ np.array([0, 0, MASS * G]), np.cross([0, 0, ZG], f_w)])
    # actuators
    n = rpm / 60
    v_a = 0.944 * speed
    kt_slope, kq_slope = (KT_MAX - KT0) / J_MAX, (KQ_MAX - KQ0) / J_MAX
    if n > 0:
        thrust = RHO * PROP_D**4 * (KT0 * abs(n) * n + kt_slope * v_a / PROP_D * abs(n))
        torque = RHO * PROP_D**5 * (KQ0 * abs(n) * n + kq_slope * v_a / PROP_D * abs(n))
    else:
        thrust, torque = RHO * PROP_D**4 * KT0 * abs(n) * n, RHO * PROP_D**5 * KQ0 * abs(n) * n
    u_h2, u_v2 = u * u + v * v, u * u + w * w
    y_r, z_s = -FIN["rudder"] * u_h2 * d_r, -FIN["stern"] * u_v2 * d_s
    x_fins = -FIN["rudder"] * u_h2 * d_r**2 - FIN["stern"] * u_v2 * d_s**2
    tau = np.array([0.9 * thrust + x_fins, y_r, z_s, torque / 10, -X_FIN * z_s, X_FIN * y_r])
    rhs = tau + lift + cross - coriolis(M_RB, nu) @ nu - c_a @ nu - damping + restoring
    nu_dot = np.linalg.solve(M_TOTAL, rhs)
    q_dot = 0.5 * np.array([-x0 * p - y0 * qq - z0 * r, w0 * p + y0 * r - z0 * qq, w0 * qq + z0 * p - x0 * r, w0 * r + x0 * qq - y0 * p])
    act_dot = [(command[0] - d_r) / 0.1, (command[1] - d_s) / 0.1, (command[2] - rpm) / 1.0]
    return np.concatenate([rot @ nu[:3], q_dot, nu_dot, act_dot])


FRD = np.diag([1.0, -1.0, -1.0])


def coupled_schedule(t):
    """Rudder +10° from 2 s, stern planes −5° from 5 s, 1000 → 1500 rpm at 10 s (the reference's case f)."""
    return (math.radians(10) if t >= 2 else 0.0, math.radians(-5) if t >= 5 else 0.0, 1500.0 if t >= 10 else 1000.0)


@pytest.fixture(scope="module")
def coupled_runs(remus):
    """marinejax (default step) and the reference over 20 s of the coupled manoeuvre, from marinejax's own
    steady straight run at 1000 rpm (the same start for both)."""
    start = steady_start(remus, 1000.0)
    dt, steps = 0.05, 400
    commands = np.array([controls(math.degrees(a), math.degrees(b), c) for a, b, c in (coupled_schedule(k * dt) for k in range(steps))])
    sim = mj.rollout(remus, commands, initial=start)
    # the start in the reference's terms: the CB's velocity (v + ω × r), NED/FRD
    rot0 = FRD @ np.asarray(quat_to_mat(start.quaternion), float) @ FRD
    omega = np.asarray(start.angular_velocity, float)
    v_cb = np.asarray(start.velocity, float) + np.cross(omega, [0, 0, ZG])
    from scipy.spatial.transform import Rotation

    q_xyzw = Rotation.from_matrix(rot0).as_quat()
    x = np.concatenate([np.zeros(3), [q_xyzw[3], *q_xyzw[:3]], FRD @ v_cb, FRD @ omega,
                        [0.0, 0.0, float(start.actuators[2])]])
    ref = []
    for k in range(steps):
        command = coupled_schedule(k * dt)
        sol = solve_ivp(reference_rhs, (k * dt, (k + 1) * dt), x, method="DOP853", rtol=1e-10, atol=1e-10, args=(command,))
        x = sol.y[:, -1]
        x[3:7] /= np.linalg.norm(x[3:7])
        ref.append(x.copy())
    return start, sim, np.array(ref), commands


def errors_against(start, sim, ref):
    """(max position error of the CB (m), max attitude error (°)) of a marinejax run against the reference."""
    from scipy.spatial.transform import Rotation

    rots = np.asarray(quat_to_mat(sim.quaternion), float)
    cb = np.asarray(sim.position, float) + rots @ np.array([0, 0, ZG])
    cb0 = np.asarray(start.position, float) + np.asarray(quat_to_mat(start.quaternion), float) @ np.array([0, 0, ZG])
    ours = (cb - cb0) @ FRD  # NED displacement of the CB
    ref_rot = Rotation.from_quat(np.concatenate([ref[:, 4:7], ref[:, 3:4]], axis=1)).as_matrix()
    ours_rot = np.einsum("ij,tjk,kl->til", FRD, rots, FRD)
    cos = np.clip((np.einsum("tij,tij->t", ref_rot, ours_rot) - 1) / 2, -1, 1)
    return np.linalg.norm(ours - ref[:, :3], axis=1).max(), math.degrees(np.arccos(cos).max())


def test_coupled_manoeuvre_matches_an_independent_integration(coupled_runs):
    """Within 1 cm and 0.5° over 20 s at the default step (issue #22's bounds), the CB's positions compared."""
    start, sim, ref, _ = coupled_runs
    position_error, attitude_error = errors_against(start, sim, ref)
    travelled = np.linalg.norm(ref[-1, :3])
    heading = math.degrees(abs(math.atan2(ref[-1, 1] - ref[-2, 1], ref[-1, 0] - ref[-2, 0])))
    print(f"\nREMUS coupled manoeuvre: {travelled:.1f} m, course {heading:.0f} deg; max position error "
          f"{position_error * 1000:.2f} mm, attitude {attitude_error:.3f} deg")
    assert travelled > 30 and heading > 60
    assert position_error < 0.01 and attitude_error < 0.5


def test_convergence_order_on_the_coupled_manoeuvre(remus, coupled_runs):
    """Halving the physics step (50 → 25 → 12.5 ms) divides the error by about 4: second order
    (measured ÷ 4.0 then ÷ 5.2: at 12.5 ms the error, 0.09 mm, is near float32's floor)."""
    start, _, ref, commands = coupled_runs
    errors = [errors_against(start, mj.rollout(remus, commands, initial=start, substeps=k), ref)[0] for k in (1, 2, 4)]
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    print(f"\nREMUS position errors {[f'{e * 1000:.3f} mm' for e in errors]}, ratios {ratios[0]:.2f}, {ratios[1]:.2f}")
    for r in ratios:
        assert 3.0 < r < 6.0


@pytest.fixture(scope="module")
def four_fin():
    return torpedo_manoeuvres(mj.load_vehicle("remus100_four_fin"))


@pytest.mark.parametrize("quantity, tolerance", [
    ("terminal speed, 1525 rpm", 1e-3), ("turning diameter, rudder 15°", 5e-3), ("turn rate, rudder 15°", 5e-3),
    ("heel into the turn, rudder 15°", 0.02), ("pitch after 5 s of stern planes 10°", 0.01),
    ("depth gained in those 5 s", 0.02), ("roll after 10 s, all four fins at +5°", 0.01),
    ("roll period, free decay from 10°", 0.01),
])
def test_the_four_fin_variant_reproduces_its_reference_implementation(four_fin, quantity, tolerance):
    """The reference's four-fin torpedo (validation.FOUR_FIN_REFERENCE): the same hull, four fins
    commanded one by one; measured differences 0.00-0.08 %, the roll period 0.3 % at the 50 ms step."""
    reference, _ = FOUR_FIN_REFERENCE[quantity]
    assert four_fin[quantity] == pytest.approx(reference, rel=tolerance)


def test_four_fins_roll_the_vehicle_and_steer_like_a_rudder_and_stern_planes():
    """All four fins at +δ make a pure roll moment (port side down); the steering mix turns the
    REMUS's rudder and stern-plane commands into the four fins' (top +, bottom −; port −, starboard +)."""
    from marinejax.actuators.fin import steering_mix

    vehicle = mj.load_vehicle("remus100_four_fin")
    np.testing.assert_array_equal(steering_mix(vehicle.sys.actuators),
                                  [[1, 0, 0], [-1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, 1]])
    wrench = np.zeros(6)
    for g in vehicle.sys.actuators[:2]:
        state = np.full(g.size, np.radians(5), np.float32)
        wrench += np.asarray(g.kind.wrench(g.design, g.params, state, np.array([2.0, 0, 0, 0, 0, 0], np.float32)))
    assert wrench[3] < -0.1  # N m, FLU roll: port side down
    np.testing.assert_allclose(wrench[[0, 1, 2, 4, 5]], 0.0, atol=1e-6)


def test_videos_turn_the_fins_with_their_deflection():
    """The renderer turns each fin's geoms (the MJCF's marinejax:fin_geoms) about x̂ × n̂ by its state:
    the rudder's leading edge goes to port (+y) at a positive deflection, and the frame changes."""
    from marinejax.render import FrameRenderer

    vehicle = mj.load_vehicle("remus100")
    renderer = FrameRenderer(vehicle.mj_model, 160, 120, vehicle.sys.qpos_adr)
    try:
        pose = (np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3))
        still = renderer.frame(*pose)
        turned = renderer.frame(*pose, fin_angles={"rudder1": np.radians(15)})
        rudder = [g for site, g, _ in renderer.fins if site == "rudder1"][0]
        chord = renderer.data.geom_xmat[rudder[0]].reshape(3, 3)[:, 0]  # the fin box's x axis, world (= body here)
        np.testing.assert_allclose(chord, [np.cos(np.radians(15)), np.sin(np.radians(15)), 0.0], atol=1e-6)
        assert np.abs(still.astype(int) - turned).sum() > 0
        back = renderer.frame(*pose, fin_angles={"rudder1": 0.0})
        np.testing.assert_array_equal(back, still)
    finally:
        renderer.close()


def test_a_malformed_fin_or_propeller_names_its_group_and_setting(tmp_path):
    from marinejax.vehicle import model_dir

    base = (model_dir() / "remus100.xml").read_text()
    cases = {
        "fin angle": (base.replace('"marinejax:rudder:max_angle" data="0.2617993877991494"', '"marinejax:rudder:max_angle" data="3"'),
                      r"rudder.*max_angle"),
        "fin lift": (base.replace('"marinejax:stern:lift_slope" data="0.7"', '"marinejax:stern:lift_slope" data="-0.7"'), r"stern.*lift_slope"),
        "propeller": (base.replace('<numeric name="marinejax:propeller:diameter" data="0.14"/>', ""), r"propeller.*diameter"),
        "fin site": (base.replace('<site name="stern1"', '<site name="sternX"'), "stern1..sternN"),
    }
    for what, (text, match) in cases.items():
        path = tmp_path / f"{what.replace(' ', '_')}.xml"
        path.write_text(text)
        with pytest.raises(UserError, match=match):
            mj.load_vehicle(str(path))
