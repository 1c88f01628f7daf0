"""The autopilot task of torpedo AUVs: set-points per segment, its errors, start and observation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.errors import UserError


@pytest.fixture(scope="module")
def env():
    return mj.make("Remus100-Autopilot")


@pytest.fixture(scope="module")
def run(env):
    """4 episodes of 60 s at 10 Hz under a fixed action (propeller at 2/3 of its range, fins at 0)."""
    keys = jax.random.split(jax.random.PRNGKey(0), 4)

    def episode(key):
        state = env.reset(key)
        action = jnp.array([0.0, 0.0, 0.3])

        def body(s, _):
            s = env.step(s, action)
            return s, (s.obs, s.metrics, s.pipeline_state.physics.data.qpos[2], s.info["time"])

        return state, jax.lax.scan(body, state, None, length=env.config.episode_length)[1]

    return jax.jit(jax.vmap(episode))(keys)


def test_set_points_are_drawn_within_their_ranges_and_switch_per_segment(env, run):
    start, (obs, metrics, z, time) = run
    task = start.info["task"]
    c = env.config
    assert task.depth.shape == (4, c.segments)
    assert np.all((np.asarray(task.depth) >= c.depth_range[0]) & (np.asarray(task.depth) <= c.depth_range[1]))
    assert np.all(np.abs(np.diff(np.asarray(task.depth), axis=1)) <= c.depth_step + 1e-5)
    assert np.all((np.asarray(task.speed) >= c.speed_range[0]) & (np.asarray(task.speed) <= c.speed_range[1]))
    # the observed depth set-point (field set_point_depth, /10) is the one of the next step: the first
    # segment's after steps 1..299, the second's from step 300 on
    f = env.observation_fields()
    upcoming = np.asarray(obs[:, :, f["set_point_depth"]])[..., 0] * 10
    half = int(round(c.segment_duration / c.control_dt))
    np.testing.assert_allclose(upcoming[:, : half - 1], np.asarray(task.depth[:, :1]).repeat(half - 1, 1), rtol=1e-6)
    np.testing.assert_allclose(upcoming[:, half - 1 :], np.asarray(task.depth[:, 1:]).repeat(half + 1, 1), rtol=1e-6)
    # the depth error statistic of step k is |set-point of step k − z|; the observation's is the
    # upcoming set-point's, clipped
    of_step = np.concatenate([np.asarray(task.depth[:, :1]).repeat(half, 1), np.asarray(task.depth[:, 1:]).repeat(half, 1)], 1)
    np.testing.assert_allclose(np.asarray(metrics["position_error"]), np.abs(of_step - np.asarray(z)), atol=1e-4)
    observed = np.asarray(obs[:, :, f["depth_error"]])[..., 0]
    np.testing.assert_allclose(np.abs(observed), np.minimum(np.abs(upcoming - np.asarray(z)), c.depth_clip), atol=1e-4)


def test_the_evaluation_window_is_the_settled_end_of_each_segment(env):
    c = env.config
    t = c.control_dt * np.arange(1, c.episode_length + 1)
    window = np.asarray(env.error_window(t))
    per_segment = int(round(c.settled / c.control_dt))
    assert window.sum() == c.segments * per_segment
    half = int(round(c.segment_duration / c.control_dt))
    assert window[half - per_segment : half].all() and not window[: half - per_segment].any()


def test_the_vehicle_starts_near_its_first_set_point_moving_forward(env, run):
    start, _ = run
    c = env.config
    vs = jax.vmap(env.plant.vehicle_state)(start.pipeline_state)
    depth0 = np.asarray(start.info["task"].depth[:, 0])
    assert np.all(np.abs(np.asarray(vs.position[:, 2]) - depth0) <= c.start_depth_error + 1e-5)
    speed = np.asarray(vs.velocity[:, 0])
    assert np.all((speed >= c.speed_range[0]) & (speed <= c.speed_range[1]))
    assert np.all(np.asarray(vs.actuators[:, 2]) > 0)  # the propeller already turning


def test_it_is_a_torpedo_task_and_bad_settings_are_refused():
    assert "BlueROV2-Autopilot" not in mj.list_envs() and "Remus100-AutopilotDisturbed" in mj.list_envs()
    with pytest.raises(UserError, match="integral_time_constant"):
        mj.make("Remus100-Autopilot", integral_time_constant=2.0)
    with pytest.raises(UserError, match="settled"):
        mj.make("Remus100-Autopilot", settled=70.0)
