"""Path following for torpedo AUVs: the paths' geometry, the closest point the task keeps, its errors
and observation, and the line-of-sight autopilot that follows the paths."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.envs import paths
from marinejax.envs.cruising import current_margin
from marinejax.errors import UserError
from marinejax.frames import quat_to_mat


def _dense(kind, path, s_max, step=0.01):
    s = jnp.arange(-5.0, s_max, step)
    return np.asarray(jax.vmap(lambda x: paths.point(kind, path, x)[0])(s)), np.asarray(s)


@pytest.mark.parametrize("kind", paths.KINDS)
def test_paths_are_continuous_with_unit_tangents_and_keep_their_radius(kind):
    config = paths.PathConfig()
    for seed in range(3):
        path = paths.sample(kind, jax.random.PRNGKey(seed), config)
        points, s = _dense(kind, path, 400.0, step=0.05)
        steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
        # arc length: consecutive points 5 cm apart along the path are 5 cm apart in space (no jumps;
        # float32 coordinates of up to 200 m and angles of up to 20 rad carry 1e-4 m of rounding each)
        np.testing.assert_allclose(steps, 0.05, atol=3e-4 if kind != "lemniscate" else 1e-3)
        tangents = np.asarray(jax.vmap(lambda x: paths.point(kind, path, x)[1])(jnp.asarray(s[::100])))
        np.testing.assert_allclose(np.linalg.norm(tangents, axis=1), 1.0, atol=2e-3)
        # the tightest radius of curvature in plan view (the course's turn per 5 m) is within what the
        # REMUS can turn; the climb angle changes by at most the leg grades' difference
        course = np.unwrap(np.arctan2(tangents[:, 1], tangents[:, 0]))
        assert 5.0 / max(np.abs(np.diff(course)).max(), 1e-9) > 24.0
        assert np.abs(np.diff(np.arcsin(tangents[:, 2]))).max() <= 2 * np.arctan(config.leg_grade) + 1e-3
        start = np.asarray(paths.point(kind, path, jnp.zeros(()))[0])
        assert config.depth[0] - 1e-3 <= start[2] <= config.depth[1] + 1e-3


def test_waypoint_legs_turn_by_the_drawn_angles_on_arcs_of_the_fillet_radius():
    config = paths.PathConfig(legs=3, turn=(1.0, 1.0), leg_grade=0.0)
    path = paths.sample("lines", jax.random.PRNGKey(3), config)
    assert path.start_s.shape == (5,)  # straight, arc, straight, arc, straight
    course = lambda s: np.arctan2(*np.asarray(paths.point("lines", path, jnp.asarray(s))[1])[[1, 0]])  # noqa: E731
    ends = np.asarray(path.start_s)
    turns = [np.angle(np.exp(1j * (course(ends[i + 1] + 1.0) - course(ends[i] - 1.0)))) for i in (1, 3)]
    np.testing.assert_allclose(np.abs(turns), 1.0, atol=1e-4)
    np.testing.assert_allclose(ends[2] - ends[1], config.fillet_radius * 1.0, rtol=1e-5)  # the arc's length R·|turn|
    # on the arc, every point is at the fillet radius from its centre
    on_arc = np.asarray(paths.point("lines", path, jnp.asarray(ends[1] + 7.0))[0])
    np.testing.assert_allclose(np.linalg.norm(on_arc[:2] - np.asarray(path.center[1])[:2]), config.fillet_radius, rtol=1e-5)


@pytest.mark.parametrize("kind", ["lines", "lemniscate"])
def test_projection_finds_the_closest_point_as_a_dense_search_does(kind):
    path = paths.sample(kind, jax.random.PRNGKey(5), paths.PathConfig())
    points, s = _dense(kind, path, 200.0)
    rng = np.random.default_rng(0)
    for s_true in rng.uniform(10.0, 180.0, 20):
        p, t = (np.asarray(a) for a in paths.point(kind, path, jnp.asarray(s_true)))
        normal = np.cross(t, rng.normal(size=3))
        q = p + 3.0 * normal / np.linalg.norm(normal)  # 3 m off the path
        found = float(paths.project(kind, path, jnp.asarray(s_true - 0.3), jnp.asarray(q)))  # from where it was a step ago
        nearby = np.abs(s - s_true) < 10.0  # the nearest part of the path (not the lemniscate's other branch)
        best = np.min(np.linalg.norm(points[nearby] - q, axis=1))
        got = np.linalg.norm(np.asarray(paths.point(kind, path, jnp.asarray(found))[0]) - q)
        assert got == pytest.approx(best, abs=2e-3)


@pytest.fixture(scope="module")
def env():
    return mj.make("Remus100-CircleFollowing")


def test_errors_and_observation_follow_the_vehicle_along_the_path(env):
    """A straight run from near the start of a circle: the cross-track error is the distance to the
    circle, the along-track speed is ds/dt, and the observed closest point is that offset in the body frame."""
    keys = jax.random.split(jax.random.PRNGKey(0), 3)

    def episode(key):
        s = env.reset(key)

        def body(s, _):
            s = env.step(s, jnp.array([0.0, 0.0, 0.2]))
            vs = env.plant.vehicle_state(s.pipeline_state)
            return s, (s.metrics, s.info["task"].s, vs.position, s.obs)

        return s, jax.lax.scan(body, s, None, length=100)[1]

    start, (metrics, arc, position, obs) = jax.jit(jax.vmap(episode))(keys)
    task = start.info["task"]
    for e in range(3):
        circle = jax.tree.map(lambda x: x[e], task.path)
        centre, radius = np.asarray(circle.center), float(circle.size)
        horizontal = np.linalg.norm(np.asarray(position[e, :, :2]) - centre[:2], axis=1) - radius
        vertical = np.asarray(position[e, :, 2]) - centre[2]
        np.testing.assert_allclose(np.asarray(metrics["position_error"][e]), np.hypot(horizontal, vertical), atol=2e-3)
        speed = np.diff(np.concatenate([[0.0], np.asarray(arc[e])])) / env.config.control_dt
        np.testing.assert_allclose(np.asarray(metrics["speed_error"][e]), np.abs(float(task.speed[e]) - speed), atol=2e-3)
    f = env.observation_fields()
    offset = np.linalg.norm(np.asarray(obs[..., f["position_error"]]), axis=-1)
    np.testing.assert_allclose(offset, np.asarray(metrics["position_error"]), atol=1e-4)
    assert np.all(np.diff(np.asarray(arc), axis=1) > 0)  # moving forward along the path


def test_line_of_sight_autopilot_follows_the_circle(env):
    from marinejax.controllers import TorpedoAutopilotConfig, torpedo_autopilot
    from marinejax.statistics import rollout_controller, summarize

    config = TorpedoAutopilotConfig(heading_gain=5.0, heading_derivative_time=1.0, lookahead=5.0)
    stats = summarize(env, rollout_controller(env, torpedo_autopilot(env, config), 8, seed=1))
    # measured: median 0.05 m, mean 0.15 m; the vehicle at 1-2 m/s on circles of 25-50 m radius
    assert stats["position_error_median_m"] < 0.1 and stats["position_error_mean_m"] < 0.3
    assert stats["speed_error_mean"] < 0.02 and stats["terminated_episodes"] == 0


def test_path_following_is_for_torpedoes_and_bad_settings_are_refused():
    assert "Remus100-WaypointFollowingDisturbed" in mj.list_envs() and "BlueROV2-CircleFollowing" not in mj.list_envs()
    with pytest.raises(UserError, match="path.turn"):
        mj.make("Remus100-WaypointFollowing", path={"turn": (0.5, 4.0)})
    with pytest.raises(UserError, match="unknown path kind 'square'"):
        paths.check_kind("square")
    with pytest.raises(UserError, match="integral_time_constant"):
        mj.make("Remus100-CircleFollowing", integral_time_constant=-1.0)
    with pytest.raises(UserError, match="config 'settle_time' must be finite and >= 0, got -1.0"):
        mj.make("Remus100-CircleFollowing", settle_time=-1.0)
    with pytest.raises(UserError, match="config 'start_offset' must be finite and >= 0, got -0.5"):
        mj.make("Remus100-CircleFollowing", start_offset=-0.5)


def _ground_radius(vehicle, sys, rpm, current, seconds=400.0, dt=0.1):
    """Full-rudder turn of `vehicle` simulated with `sys` at propeller speed `rpm` in a uniform
    current (3,) m/s: (the widest radius of curvature of the ground track in plan view over the last
    revolution, where the current carries it along: the tightest circle over the ground it can
    follow all the way round, m; the mean speed through the water there, m/s)."""
    from marinejax.physics import initial_state, rollout

    steps = int(seconds / dt)
    commands = np.tile(np.array([1.0, 0.0, 2.0 * rpm / 1525.0 - 1.0], np.float32), (steps, 1))  # [0, 1525] rpm ↔ [−1, 1]
    start = initial_state(vehicle, velocity=(rpm / 1525.0 * 2.554, 0.0, 0.0), actuators=(0.0, 0.0, rpm))
    traj = rollout(vehicle, commands, start, control_dt=dt, substeps=2, sys=sys, current=current)
    last = slice(steps // 5, None)  # the steady turn: more than a revolution (at 0.5 m/s one takes 5 minutes)
    rot = np.asarray(jax.vmap(quat_to_mat)(traj.quaternion))[last]
    ground = np.einsum("tij,tj->ti", rot, np.asarray(traj.velocity)[last])  # world, over the ground
    water = ground - np.asarray(current)
    accel = np.gradient(ground[:, :2], dt, axis=0)
    curvature = np.abs(ground[:, 0] * accel[:, 1] - ground[:, 1] * accel[:, 0]) / np.linalg.norm(ground[:, :2], axis=1) ** 3
    return 1.0 / curvature.min(), float(np.linalg.norm(water, axis=1).mean())


def test_a_disturbed_path_is_one_the_weakest_fins_can_turn_downstream_in_the_episodes_current():
    """The fitted path's tightest radius (the drawn 25 m × `turn_scale`) is at least what the REMUS
    100 flies at full rudder with the randomization's weakest fins, carried by the current at the
    commanded ground speed: the turn the path asks is one the vehicle can make."""
    env = mj.make("Remus100-CircleFollowingDisturbed")
    vehicle = env.vehicle
    f_min = env.config.randomization.fin_lift_scale[0]
    weak = vehicle.sys.replace(actuators=tuple(
        g.replace(params=g.params.replace(lift_scale=g.params.lift_scale * f_min)) if g.kind.name == "fin" else g
        for g in vehicle.sys.actuators))
    full, full_speed = _ground_radius(vehicle, vehicle.sys, 1525.0, np.zeros(3))
    slow, slow_speed = _ground_radius(vehicle, vehicle.sys, 500.0, np.zeros(3))
    weak_radius, _ = _ground_radius(vehicle, weak, 500.0, np.zeros(3))
    # the reference's turning circle at full speed (37 m across); slower, a wider one, at most as
    # 1/U (the bound `turn_scale` rests on); weaker fins widen it, at most as 1/f
    assert full == pytest.approx(36.92 / 2, rel=0.01) and slow_speed < 0.4 * full_speed
    assert 1.2 * full < slow <= full * full_speed / slow_speed and slow < weak_radius <= slow / f_min
    for speed, drift in ((1.0, 0.3), (1.0, 0.5), (1.5, 0.5)):
        # the propeller speed that gives the water speed V − c in the steady turn (about linear)
        rpm = 500.0
        for _ in range(2):
            _, water = _ground_radius(vehicle, weak, rpm, np.zeros(3))
            rpm *= (speed - drift) / water
        flown, water = _ground_radius(vehicle, weak, rpm, np.array([drift, 0.0, 0.0]))
        assert water == pytest.approx(speed - drift, rel=0.02)
        mean = jnp.array([drift - current_margin(env.config), 0.0, 0.0])  # the OU margin is part of the drift
        asked = paths.PathConfig().radius[0] * float(env.turn_scale(jnp.asarray(speed), mean))
        # without the fit, the 25 m circle is tighter than the vehicle can fly downstream
        assert flown > paths.PathConfig().radius[0] * 1.5 and asked >= flown, (speed, drift, flown, asked)


@pytest.mark.parametrize("kind", paths.KINDS)
def test_a_turn_scale_widens_every_turn_and_keeps_the_start(kind):
    config = paths.PathConfig()
    key = jax.random.PRNGKey(7)
    drawn, wide = paths.sample(kind, key, config), paths.sample(kind, key, config, jnp.asarray(2.5))
    radius = lambda p: p.radius if kind == "lines" else p.size  # noqa: E731
    np.testing.assert_allclose(float(radius(wide)), 2.5 * float(radius(drawn)), rtol=1e-6)
    for a, b in zip(paths.point(kind, drawn, jnp.zeros(())), paths.point(kind, wide, jnp.zeros(()))):
        np.testing.assert_allclose(np.asarray(b), np.asarray(a), atol=1e-4)  # start point and direction
    if kind == "lines":  # the legs keep their lengths: only the arcs between them grow
        np.testing.assert_allclose(np.diff(np.asarray(wide.start_s))[::2], np.diff(np.asarray(drawn.start_s))[::2], rtol=1e-5)
    # no scale: exactly the drawn path
    for a, b in zip(jax.tree.leaves(drawn), jax.tree.leaves(paths.sample(kind, key, config, 1.0))):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # a grade scale flattens its climbs and dives (dz per m along the path) and nothing else
    flat = paths.sample(kind, key, config, jnp.asarray(2.5), jnp.asarray(0.25))
    def grade(path, s=1.0):  # dz per m of horizontal travel at s (m): on the first straight of the legs, anywhere on a helix
        tangent = paths.point(kind, path, jnp.asarray(s))[1]
        return float(tangent[2] / jnp.linalg.norm(tangent[:2]))

    if kind in ("lines", "helix"):
        assert abs(grade(drawn)) > 0.005
    np.testing.assert_allclose(grade(flat), 0.25 * grade(wide), atol=1e-6)
    np.testing.assert_allclose(float(radius(flat)), float(radius(wide)), rtol=1e-6)


def test_the_disturbed_task_fits_its_path_to_the_episodes_current_and_the_nominal_keeps_it():
    disturbed, nominal = mj.make("Remus100-CircleFollowingDisturbed"), mj.make("Remus100-CircleFollowing")
    keys = jax.random.split(jax.random.PRNGKey(2), 16)
    c = disturbed.config
    for env in (disturbed, nominal):
        states = jax.vmap(env.reset)(keys)
        task = states.info["task"]
        drawn = jax.vmap(lambda k: paths.sample("circle", jax.random.split(jax.random.split(k, 6)[1])[0], c.path))(keys)
        speed, mean = np.asarray(task.speed, np.float64), np.asarray(states.pipeline_state.current.mean, np.float64)
        if env is nominal:
            np.testing.assert_array_equal(np.asarray(task.path.size), np.asarray(drawn.size))
            continue
        drift = np.linalg.norm(mean[:, :2], axis=1) + 2 * np.sqrt(2) * c.current.ou_sigma
        expected = np.maximum(1.0, (speed / (speed - drift)) ** 3) / c.randomization.fin_lift_scale[0]
        np.testing.assert_allclose(np.asarray(task.path.size), np.asarray(drawn.size) * expected, rtol=1e-5)
        assert expected.min() >= 1 / 0.8 and expected.max() > 2.0  # every episode widened; the strong currents more
        # the vehicle starts on the fitted path as on the drawn one: within the start offset
        assert np.asarray(states.metrics["position_error"]).max() <= np.hypot(c.start_offset, c.start_offset / 2) + 1e-4
    # a disturbed helix is widened as the circle and keeps its descent per turn: its grade falls as much
    helix = mj.make("Remus100-HelixFollowingDisturbed")
    task = jax.vmap(helix.reset)(keys).info["task"]
    drawn = jax.vmap(lambda k: paths.sample("helix", jax.random.split(jax.random.split(k, 6)[1])[0], helix.config.path))(keys)
    assert np.all(np.asarray(task.path.size) > 1.2 * np.asarray(drawn.size))
    np.testing.assert_allclose(np.asarray(task.path.pitch), np.asarray(drawn.pitch), rtol=1e-5)


@pytest.mark.parametrize("name,kind", [("Remus100-CircleFollowingDisturbed", "circle"), ("Remus100-WaypointFollowingDisturbed", "lines")])
def test_under_a_current_the_vehicle_starts_crabbed_into_it(name, kind):
    """Under a (horizontal) current the start is under way in it: bow first through the water, its
    velocity over the ground the commanded speed along the path (with no drawn heading error), the
    propeller at the speed through the water; with one, the heading is off the crab course by it."""
    keys = jax.random.split(jax.random.PRNGKey(3), 16)
    for error in (0.0, None):
        env = mj.make(name, start_heading_error=error) if error is not None else mj.make(name)
        states = jax.vmap(env.reset)(keys)
        vs = jax.vmap(env.plant.vehicle_state)(states.pipeline_state)
        current = np.asarray(states.pipeline_state.current.value, np.float64)
        rot = np.asarray(jax.vmap(quat_to_mat)(vs.quaternion), np.float64)
        ground = np.einsum("eij,ej->ei", rot, np.asarray(vs.velocity, np.float64))
        water = np.einsum("eji,ej->ei", rot, ground - current)  # body frame
        speed = np.linalg.norm(water, axis=1)
        assert np.all(current[:, 2] == 0.0) and np.linalg.norm(current, axis=1).max() > 0.2  # horizontal, and strong
        np.testing.assert_allclose(water[:, 1:], 0.0, atol=1e-5)  # bow first through the water
        np.testing.assert_allclose(np.asarray(vs.actuators)[:, 2], speed / env.config.top_speed * 1525.0, rtol=1e-4)
        task = states.info["task"]
        tangent = np.asarray(jax.vmap(lambda p: paths.point(kind, p, jnp.zeros(()))[1])(task.path), np.float64)
        if error == 0.0:
            crab = np.degrees(np.arccos(np.clip(np.einsum("ei,ei->e", rot[:, :, 0], tangent), -1.0, 1.0)))
            np.testing.assert_allclose(ground, np.asarray(task.speed)[:, None] * tangent, atol=1e-4)
            assert crab.max() > 10.0  # a strong cross current: turned well into it
        else:  # the bow off the crab course (the water velocity that flies the path) by the drawn error
            needed = np.asarray(task.speed)[:, None] * tangent - current
            off = np.arccos(np.clip(np.einsum("ei,ei->e", rot[:, :, 0], needed) / np.linalg.norm(needed, axis=1), -1.0, 1.0))
            assert off.max() <= env.config.start_heading_error + 1e-4 and off.max() > 0.5 * env.config.start_heading_error


def test_a_current_faster_than_the_path_is_refused():
    with pytest.raises(UserError, match=r"'path.speed' \(0.5, 2.0\) must stay above the current's fastest horizontal drift"):
        mj.make("Remus100-CircleFollowingDisturbed", path={"speed": (0.5, 2.0)})
    mj.make("Remus100-CircleFollowing", path={"speed": (0.5, 2.0)})  # no current: any speed


def _level_pitch_range(vehicle, cob_shift):
    """Steady pitch (deg, FLU: negative nose up) of `vehicle` at 1 m/s with its centre of buoyancy
    shifted by `cob_shift` (3,) m, stern planes at either limit: (lowest, highest)."""
    from marinejax.frames import quat_to_euler
    from marinejax.physics import initial_state, rollout

    sys = vehicle.sys.replace(hydro=vehicle.sys.hydro.replace(center_of_buoyancy=vehicle.sys.hydro.center_of_buoyancy + jnp.asarray(cob_shift)))
    rpm = 608.0  # 1 m/s in straight flight (2.51 m/s at 1525 rpm)
    pitch = []
    for stern in (-1.0, 1.0):
        commands = np.tile(np.array([0.0, stern, 2.0 * rpm / 1525.0 - 1.0], np.float32), (600, 1))
        traj = rollout(vehicle, commands, initial_state(vehicle, velocity=(1.0, 0.0, 0.0), actuators=(0.0, 0.0, rpm)),
                       control_dt=0.1, substeps=2, sys=sys)
        pitch.append(float(np.degrees(quat_to_euler(traj.quaternion[-1])[1])))
    return min(pitch), max(pitch)


def test_a_torpedos_trim_randomization_leaves_its_stern_planes_room_to_fly_level():
    """The torpedo tasks draw the centre of buoyancy within ±1 mm (the ROVs: ±5 mm). At 1 m/s the
    REMUS 100's stern planes hold ±9.5° of pitch; 5 mm of trim error would leave it unable to fly
    level (it could not climb or not dive), 1 mm leaves it more than 5° either way."""
    env = mj.make("Remus100-CircleFollowingDisturbed")
    offset = env.config.randomization.cob_offset
    assert offset == 0.001 and mj.make("BlueROV2Heavy-StationKeepingDisturbed").config.randomization.cob_offset == 0.005
    low, high = _level_pitch_range(env.vehicle, (0.0, 0.0, 0.0))
    assert low == pytest.approx(-high, abs=0.3) and 8.0 < high < 11.0
    for shift in (offset, -offset):
        low, high = _level_pitch_range(env.vehicle, (shift, 0.0, 0.0))
        assert low < -5.0 and high > 5.0
    low, high = _level_pitch_range(env.vehicle, (0.005, 0.0, 0.0))
    assert high < -3.0  # nose up whatever the stern planes do
