"""Closed-form checks of the physics step (BlueROV2 Heavy, von Benzon 2022 parameters).

Most checks share one compiled rollout shape (4 vehicles x 1000 steps, wrench mode, one physics step
per control step), called with different inputs and step sizes, so the module compiles it once.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.frames import quat_from_euler, quat_to_euler, quat_to_mat
from marinejax.hydro import kinetic_energy, potential_energy

B, T = 4, 1000  # the shared rollout shape


@pytest.fixture(scope="module")
def heavy():
    return mj.load_vehicle("bluerov2_heavy")


def rigid(vehicle):
    return float(vehicle.sys.model.body_mass[1]), np.asarray(vehicle.sys.model.body_inertia[1])


def net_buoyancy(vehicle):
    """B - W (N), positive = buoyant."""
    h = vehicle.sys.hydro
    g = -float(vehicle.sys.model.opt.gravity[2])
    return float(h.fluid_density * g * h.volume) - rigid(vehicle)[0] * g


def make_state(vehicle, rpy=None, velocity=None, angular_velocity=None):
    rpy = np.zeros((B, 3)) if rpy is None else np.asarray(rpy, float)
    quat = np.stack([np.asarray(quat_from_euler(*r)) for r in rpy])
    return mj.VehicleState(
        position=jnp.zeros((B, 3)),
        quaternion=jnp.asarray(quat, jnp.float32),
        velocity=jnp.asarray(np.zeros((B, 3)) if velocity is None else velocity, jnp.float32),
        angular_velocity=jnp.asarray(np.zeros((B, 3)) if angular_velocity is None else angular_velocity, jnp.float32),
        actuators=jnp.zeros((B, vehicle.num_actuators)),
    )


def run(vehicle, wrench, state, dt=0.01, current=None, sys=None):
    return mj.rollout(vehicle, wrench, state, control_dt=dt, substeps=1, mode="wrench", current=current, sys=sys)


def steady_speed(lin, quad, force):
    """Root of lin*u + quad*u^2 = force (u >= 0)."""
    if quad == 0:
        return force / lin
    return (-lin + math.sqrt(lin**2 + 4 * quad * force)) / (2 * quad)


# Axis steps: surge 12 N, sway 12 N, heave -15 N (down). Forces keep speeds below ~0.3 m/s where
# the Munk moment does not exceed the restoring moment (vehicles reference).
FORCES = [(0, 12.0), (1, 12.0), (2, -15.0)]


@pytest.fixture(scope="module")
def axis_steps(heavy):
    wrench = np.zeros((B, T, 6), np.float32)
    for row, (axis, f) in enumerate(FORCES):
        wrench[row, :, axis] = f
    return run(heavy, wrench, make_state(heavy))


@pytest.mark.parametrize("row", range(3))
def test_initial_acceleration_is_force_over_mass_plus_added_mass(heavy, axis_steps, row):
    axis, f = FORCES[row]
    m, _ = rigid(heavy)
    if axis == 2:
        f += net_buoyancy(heavy)
    expected = f / (m + float(heavy.sys.hydro.added_mass[axis]))
    # One Euler step from rest: v1 = a * dt exactly (drag is zero at rest).
    measured = float(axis_steps.velocity[row, 0, axis]) / 0.01
    assert measured == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize("row", range(3))
def test_steady_speed_matches_damping_root(heavy, axis_steps, row):
    axis, f = FORCES[row]
    h = heavy.sys.hydro
    if axis == 2:
        f += net_buoyancy(heavy)
    expected = math.copysign(steady_speed(float(h.linear_damping[axis]), float(h.quadratic_damping[axis]), abs(f)), f)
    measured = float(axis_steps.velocity[row, -1, axis])
    assert measured == pytest.approx(expected, rel=0.01)
    # and it has settled: < 1 % change over the last second (the slow sinking of the slightly
    # heavy vehicle couples weakly into sway through the Munk roll moment)
    assert abs(float(axis_steps.velocity[row, -100, axis]) - measured) < 0.01 * abs(measured)


@pytest.fixture(scope="module")
def passive(heavy):
    """Row 0: rolled 5 deg (small-angle period), row 1: rolled 20 deg, row 2: tumbling with
    velocities (energy), row 3: at rest, rolled 20 deg, in the Wu 2018 set is elsewhere."""
    rpy = np.radians([[5, 0, 0], [20, 0, 0], [20, 10, 30], [0, 0, 0]])
    vel = np.array([[0, 0, 0], [0, 0, 0], [0.4, 0.2, -0.1], [0, 0, 0]])
    ang = np.array([[0, 0, 0], [0, 0, 0], [0.3, -0.2, 0.5], [0, 0, 0]])
    state = make_state(heavy, rpy, vel, ang)
    return state, run(heavy, np.zeros((B, T, 6), np.float32), state)


def roll_deg(traj, row):
    return np.degrees(np.asarray(quat_to_euler(traj.quaternion[row]))[:, 0])


def test_small_angle_roll_period(heavy, passive):
    _, traj = passive
    roll = roll_deg(traj, 0)
    t = np.asarray(traj.time)
    # downward zero crossings, linearly interpolated
    idx = np.where((roll[:-1] > 0) & (roll[1:] <= 0))[0]
    crossings = t[idx] + (t[idx + 1] - t[idx]) * roll[idx] / (roll[idx] - roll[idx + 1])
    assert len(crossings) >= 2
    measured = float(np.mean(np.diff(crossings)))
    h = heavy.sys.hydro
    m, inertia = rigid(heavy)
    g = 9.81
    buoyancy = float(h.fluid_density * g * h.volume)
    bg = float(h.center_of_buoyancy[2])
    expected = 2 * math.pi * math.sqrt((inertia[0] + float(h.added_mass[3])) / (buoyancy * bg))
    assert measured == pytest.approx(expected, rel=0.03)


def test_rolled_vehicle_rights_itself(heavy, passive):
    _, traj = passive
    roll = roll_deg(traj, 1)
    assert roll[0] < 20.0  # the restoring moment turns it back from the first step
    # upright within about a quarter of the ~3.7 s period, and the swing decays
    first_zero = np.argmax(roll <= 0) * 0.01
    assert 0.5 < first_zero < 1.5
    assert np.max(np.abs(roll[-300:])) < 0.8 * 20.0


@pytest.mark.parametrize("dt", [0.01, 0.05])  # 0.05 s: the default and largest midpoint step
def test_energy_never_increases_without_thrust(heavy, passive, dt):
    state = passive[0]
    traj = passive[1] if dt == 0.01 else run(heavy, np.zeros((B, T, 6), np.float32), state, dt=dt)
    h = heavy.sys.hydro
    m, inertia = rigid(heavy)

    def energy(pos, quat, vel, ang):
        nu = jnp.concatenate([vel, ang])
        return kinetic_energy(h, m, inertia, nu) + potential_energy(h, m, pos, quat_to_mat(quat), 9.81)

    e = jax.vmap(energy)(traj.position[2], traj.quaternion[2], traj.velocity[2], traj.angular_velocity[2])
    e0 = energy(state.position[2], state.quaternion[2], state.velocity[2], state.angular_velocity[2])
    e = np.concatenate([[float(e0)], np.asarray(e)])
    # float32 round-off on ~1 J values allows 1e-5 J of noise; the run dissipates > 0.5 J
    assert np.max(np.diff(e)) < 1e-5
    assert e[0] - e[-1] > 0.5


def test_predictor_acceleration_equals_mujoco_forward_dynamics(heavy):
    """The midpoint predictor's acceleration (hydro_terms, whole model) is what MuJoCo computes
    under the wrench handed to it: the two halves of the integrator describe one model."""
    from mujoco import mjx

    from marinejax.physics import model_acceleration, to_physics

    sys = heavy.sys
    state = mj.initial_state(heavy, quaternion=(0.9, 0.2, 0.3, 0.1), velocity=(0.5, -0.2, 0.3), angular_velocity=(0.3, -0.4, 0.5))
    ps = to_physics(sys, state)
    thrust = jnp.linspace(-20.0, 30.0, heavy.num_actuators)
    xfrc, qacc = model_acceleration(sys, ps.data.qpos, ps.data.qvel, thrust, jnp.zeros(6), jnp.array([0.1, 0.2, 0.0]))
    data = mjx.forward(sys.model, ps.data.replace(xfrc_applied=ps.data.xfrc_applied.at[sys.body_id].set(xfrc)))
    np.testing.assert_allclose(np.asarray(qacc), np.asarray(data.qacc), atol=2e-5)
    assert np.abs(np.asarray(qacc)).max() > 1.0


def test_heave_with_large_added_mass_is_stable_and_step_size_independent(heavy):
    """Heave added mass is 1.38 x the rigid mass: a lagged scheme would diverge; ours must not."""
    wrench = np.zeros((B, T, 6), np.float32)
    wrench[:, :, 2] = np.where(np.arange(T) * 1.0 < T / 2, -20.0, 10.0)[None, :]
    velocities = {}
    for dt in (0.002, 0.01, 0.02, 0.05):  # 0.05 s: the largest step the default integrator allows
        traj = run(heavy, wrench, make_state(heavy), dt=dt)
        t = np.asarray(traj.time)
        w = np.asarray(traj.velocity[0, :, 2])
        assert np.all(np.isfinite(w)) and np.max(np.abs(w)) < 0.5
        # the switch happens at t = 500 dt, so compare on the first 2 s with the force held
        grid = np.linspace(0.1, 0.99, 40)
        velocities[dt] = np.interp(grid, t, w)
    for dt in (0.01, 0.02, 0.05):
        assert np.max(np.abs(velocities[dt] - velocities[0.002])) < 0.01  # m/s, out of ~0.3
    # after the step to +10 N (at 5 s for dt 0.01) the speed settles at the damping root
    traj = run(heavy, wrench, make_state(heavy), dt=0.01)
    h = heavy.sys.hydro
    f = 10.0 + net_buoyancy(heavy)
    expected = steady_speed(float(h.linear_damping[2]), float(h.quadratic_damping[2]), f)
    assert float(traj.velocity[0, -1, 2]) == pytest.approx(expected, rel=0.01)


def test_positive_buoyancy_surfaces(heavy):
    buoyant = heavy.sys.replace(hydro=heavy.sys.hydro.replace_values(volume=0.0140))  # +7 N
    traj = run(heavy, np.zeros((B, T, 6), np.float32), make_state(heavy), sys=buoyant)
    assert float(traj.position[0, -1, 2]) > 0.5
    heavy_traj = run(heavy, np.zeros((B, T, 6), np.float32), make_state(heavy))
    assert float(heavy_traj.position[0, -1, 2]) < -0.1  # the default set is 0.98 N heavy


def test_drifting_vehicle_takes_the_current_velocity(heavy):
    current = np.array([0.3, 0.2, 0.0], np.float32)  # m/s, world
    traj = run(heavy, np.zeros((B, T, 6), np.float32), make_state(heavy), dt=0.02, current=current)
    rot = np.asarray(jax.vmap(quat_to_mat)(traj.quaternion[0]))
    v_world = np.einsum("tij,tj->ti", rot, np.asarray(traj.velocity[0]))
    err = np.linalg.norm(v_world[:, :2] - current[:2], axis=1)
    assert err[0] > 0.2
    assert err[-1] < 0.01  # 20 s; sway has no linear damping, so the last mm/s go slowly
    assert err[-1] < err[500] < err[250] < err[50]  # 20 s < 10 s < 5 s < 1 s


def test_current_is_relative_not_absolute(heavy):
    """A vehicle moving with the current feels no drag: it keeps its speed."""
    current = np.array([0.3, 0.0, 0.0], np.float32)
    state = make_state(heavy, velocity=np.tile([0.3, 0, 0], (B, 1)))
    traj = run(heavy, np.zeros((B, T, 6), np.float32), state, current=current)
    assert abs(float(traj.velocity[0, 99, 0]) - 0.3) < 1e-3


@pytest.fixture(scope="module")
def thruster_runs(heavy):
    """Thruster mode, 2 s at 20 Hz: forward at heading 90 deg, yaw, up, nothing."""
    cmd = np.zeros((4, 40, 8), np.float32)
    cmd[0, :, :4] = [0.3, 0.3, -0.3, -0.3]  # forward (allocation X row: +, +, -, -)
    cmd[1, :, :4] = [0.3, -0.3, -0.3, 0.3]  # yaw left (N row: +, -, -, +)
    cmd[2, :, 4:] = 0.3  # verticals up
    quat = np.stack([np.asarray(quat_from_euler(0, 0, math.pi / 2))] + [np.array([1, 0, 0, 0])] * 3)
    state = mj.VehicleState(
        position=jnp.zeros((4, 3)),
        quaternion=jnp.asarray(quat, jnp.float32),
        velocity=jnp.zeros((4, 3)),
        angular_velocity=jnp.zeros((4, 3)),
        actuators=jnp.zeros((4, 8)),
    )
    return cmd, state, mj.rollout(heavy, cmd, state)  # defaults: 50 ms control, one midpoint step


def test_forward_command_moves_along_heading(thruster_runs):
    _, _, traj = thruster_runs
    p = np.asarray(traj.position[0, -1])
    assert p[1] > 0.3 and abs(p[0]) < 0.05 * p[1]  # heading 90 deg = world +y
    assert float(traj.velocity[0, -1, 0]) > 0.2  # body surge


def test_positive_yaw_command_turns_counterclockwise_seen_from_above(thruster_runs):
    _, _, traj = thruster_runs
    yaw = np.degrees(np.unwrap(np.asarray(quat_to_euler(traj.quaternion[1]))[:, 2]))
    assert yaw[-1] > 90.0 and np.all(np.diff(yaw) > 0)
    assert float(traj.angular_velocity[1, -1, 2]) > 0


def test_up_command_rises(thruster_runs):
    _, _, traj = thruster_runs
    assert float(traj.position[2, -1, 2]) > 0.3
    assert float(traj.position[3, -1, 2]) < 0.0  # passive: slightly heavy, sinks


def test_thrust_follows_first_order_lag(heavy, thruster_runs):
    _, _, traj = thruster_runs
    from marinejax.actuators.t200 import t200_thrust

    (t200,) = heavy.sys.actuators
    target = float(t200_thrust(t200.design.curve, jnp.float32(0.3), jnp.float32(16.0)))
    tau = float(t200.params.time_constant)
    # after one control step (0.05 s) the lag has covered 1 - exp(-0.05 / tau)
    assert float(traj.thrust[2, 0, 4]) == pytest.approx(target * (1 - math.exp(-0.05 / tau)), rel=1e-3)
    assert float(traj.thrust[2, -1, 4]) == pytest.approx(target, rel=1e-4)


def test_batched_equals_single_and_is_deterministic(heavy, thruster_runs):
    cmd, state, traj = thruster_runs
    single = mj.rollout(heavy, cmd[1], jax.tree.map(lambda x: x[1], state))
    again = mj.rollout(heavy, cmd[1], jax.tree.map(lambda x: x[1], state))
    np.testing.assert_allclose(np.asarray(single.position), np.asarray(traj.position[1]), atol=1e-6)
    np.testing.assert_allclose(np.asarray(single.quaternion), np.asarray(traj.quaternion[1]), atol=1e-6)
    np.testing.assert_array_equal(np.asarray(single.position), np.asarray(again.position))


def test_bad_inputs_name_the_problem(heavy):
    with pytest.raises(ValueError, match=r"\(T, 8\).*got \(10, 6\)"):
        mj.rollout(heavy, np.zeros((10, 6)))
    with pytest.raises(ValueError, match="unknown command mode 'force'"):
        mj.rollout(heavy, np.zeros((10, 6)), mode="force")
    with pytest.raises(ValueError, match="non-finite"):
        mj.rollout(heavy, np.full((10, 8), np.nan))
    with pytest.raises(ValueError, match="current must have shape"):
        mj.rollout(heavy, np.zeros((10, 8)), current=np.zeros(2))
    with pytest.raises(ValueError, match="substeps"):
        mj.rollout(heavy, np.zeros((10, 8)), substeps=0)
    with pytest.raises(ValueError, match=r"unknown integrator 'rk4'; valid: \['midpoint', 'euler'\]"):
        mj.rollout(heavy, np.zeros((10, 8)), integrator="rk4")
    with pytest.raises(ValueError, match=r"0.0600 s exceeds 0.05 s.*'midpoint'"):
        mj.rollout(heavy, np.zeros((10, 8)), control_dt=0.06)
    with pytest.raises(ValueError, match=r"0.0250 s exceeds 0.02 s.*'euler'"):
        mj.rollout(heavy, np.zeros((10, 8)), substeps=2, integrator="euler")


def test_divergence_is_reported_not_propagated(heavy):
    bad = heavy.sys.replace(hydro=heavy.sys.hydro.replace(volume=jnp.float32(np.inf)))
    with pytest.raises(mj.SimulationDiverged, match="control step 0"):
        run(heavy, np.zeros((B, T, 6), np.float32), make_state(heavy), sys=bad)


def test_rollout_is_differentiable(heavy):
    """d(final surge position)/d(surge force) through 20 physics steps matches a finite difference."""
    from marinejax.physics import control_step, to_physics, with_timestep

    sys = with_timestep(heavy.sys, 0.01)

    def final_x(force):
        ps = to_physics(sys, mj.initial_state(heavy))
        wrench = jnp.zeros(6).at[0].set(force)
        ps = jax.lax.fori_loop(0, 20, lambda _, p: control_step(sys, p, wrench, jnp.zeros(3), 1, "wrench"), ps)
        return ps.data.qpos[0]

    grad = float(jax.jit(jax.grad(final_x))(10.0))
    f = jax.jit(final_x)
    fd = (float(f(10.5)) - float(f(9.5))) / 1.0
    assert np.isfinite(grad) and grad > 0
    assert grad == pytest.approx(fd, rel=0.02)
