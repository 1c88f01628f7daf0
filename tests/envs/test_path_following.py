"""Path following for torpedo AUVs: the paths' geometry, the closest point the task keeps, its errors
and observation, and the line-of-sight autopilot that follows the paths."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.envs import paths
from marinejax.errors import UserError


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
