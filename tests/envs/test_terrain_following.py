"""Terrain following: a seabed of blocks drawn per episode, the altitude measured by the altimeter in
the MJX scene, the hull touching the seabed ending the episode, the classical autopilot on the
altimeter holding the altitude, and the autopilot's policy able to start it."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.controllers import TorpedoAutopilotConfig, torpedo_autopilot
from marinejax.envs.terrain_following import BLOCK_LENGTH, FIRST_BLOCK_X
from marinejax.errors import UserError
from marinejax.frames import quat_to_mat
from marinejax.statistics import rollout_controller
from marinejax.train.paths import plot_paths

ENV = "Remus100-TerrainFollowing"


@pytest.fixture(scope="module")
def env():
    return mj.make(ENV)


@pytest.fixture(scope="module")
def resets(env):
    return jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 32))


def test_the_seabed_is_drawn_per_episode_within_its_slope_and_the_scene_holds_it(env, resets):
    c = env.config
    tops = np.asarray(resets.info["task"].tops)
    assert tops.shape == (32, len(c.movable_geoms))
    assert np.ptp(tops[:, 0]) > 0.1  # another seabed per episode
    # a sum of sines with steepest slope max_slope: no step between blocks steeper than that
    assert np.max(np.abs(np.diff(tops, axis=1))) <= c.max_slope * BLOCK_LENGTH + 1e-4
    assert np.max(np.abs(np.diff(tops, axis=1))) > 0.5 * c.max_slope * BLOCK_LENGTH / c.waves
    layout = np.asarray(resets.info["params"].layout)
    np.testing.assert_allclose(layout[..., 2] + 10.0, tops, atol=1e-5)  # the blocks' tops, 10 m above their centres
    np.testing.assert_allclose(layout[0, :, 0], FIRST_BLOCK_X + BLOCK_LENGTH * (np.arange(32) + 0.5))
    model, _ = env.plant.world(jax.tree.map(lambda x: x[0], resets.info["params"]), jax.tree.map(lambda x: x[0], resets.pipeline_state))
    np.testing.assert_allclose(np.asarray(model.geom_pos)[np.asarray(env.plant.sys.layout_ids)], layout[0])


def test_the_vehicle_starts_at_the_commanded_altitude_and_measures_it_with_the_altimeter(env, resets):
    """Level at x = 0 at the set-point ± start_altitude_error; an ideal altimeter with one beam straight
    down (measuring from its head, 0.2 m ahead of and 0.095 m below the origin: over the same block)
    gives the true altitude, which the observation's depth error and depth set-point are made of."""
    c = env.config
    task, z = resets.info["task"], np.asarray(resets.pipeline_state.physics.data.qpos[:, 2])
    altitude = z - np.asarray(task.ground)
    assert np.all(np.abs(altitude - np.asarray(task.altitude)) <= c.start_altitude_error + 1e-5)
    assert np.all((np.asarray(task.altitude) >= c.altitude_range[0]) & (np.asarray(task.altitude) <= c.altitude_range[1]))
    exact = mj.make(ENV, sensors={"altimeter": {"ideal": True, "beams": 1, "beam_angle": 0.0}})
    states = jax.jit(jax.vmap(exact.reset))(jax.random.split(jax.random.PRNGKey(0), 32))
    reading = states.info["scene_sensors"]["altimeter"].reading
    head = exact.config.sensors.altimeter.position
    assert head[0] < 2.0 and head[2] < 0  # the REMUS 100's DVL (its MJCF file): over the first block
    np.testing.assert_allclose(np.asarray(reading.altitude), altitude + head[2], atol=1e-4)
    f = exact.observation_fields()
    np.testing.assert_allclose(np.asarray(states.obs[:, f["depth_error"]])[:, 0], np.asarray(task.altitude) - altitude, atol=1e-4)
    np.testing.assert_allclose(np.asarray(states.obs[:, f["set_point_depth"]])[:, 0] * 10,
                               np.asarray(task.ground + task.altitude), atol=1e-4)
    # the errors are the true altitude's
    np.testing.assert_allclose(np.asarray(states.metrics["position_error"]), np.abs(np.asarray(task.altitude) - altitude), atol=1e-4)


def test_its_targets_are_the_altitude_and_the_autopilots_heading_and_speed(env, resets):
    # what `best_on="targets"` chooses a checkpoint on; each other error logged over the window
    assert dict(env.targets) == {"position_error": 0.2, "heading_error_deg": 2.0, "speed_error": 0.05}
    assert set(env.targets) <= set(env.error_names)
    assert {"window_heading_error_deg", "window_speed_error"} <= set(resets.metrics)


def test_without_bottom_lock_the_last_valid_altitude_is_held(env):
    """An altimeter that loses every update after the first: the observed altitude error stays the
    start's while the vehicle climbs away."""
    lost = mj.make(ENV, sensors={"altimeter": {"dropout": 0.999999}})
    state = jax.jit(lost.reset)(jax.random.PRNGKey(3))
    assert not bool(state.info["scene_sensors"]["altimeter"].reading.lock)  # the first update lost too
    f = lost.observation_fields()
    first = float(state.obs[f["depth_error"]][0])
    np.testing.assert_allclose(first, 0.0, atol=1e-6)  # held: the set-point's reading, level
    step = jax.jit(lost.step)
    for _ in range(20):
        state = step(state, jnp.array([0.0, -1.0, 0.5]))  # stern planes nose up: climbing
    assert float(state.metrics["position_error"]) > 0.3  # the true altitude changed
    # the observed one is still the first reading (along the DVL's axis), only turned by the attitude
    task = state.info["task"]
    np.testing.assert_allclose(float(task.held), float(task.altitude) + lost.config.sensors.altimeter.position[2], atol=1e-6)
    up = np.asarray(quat_to_mat(state.pipeline_state.physics.data.qpos[3:7]))[2]
    measured = float(task.held) * up[2] - up @ np.asarray(lost.config.sensors.altimeter.position)
    np.testing.assert_allclose(float(state.obs[f["depth_error"]][0]), float(task.altitude) - measured, atol=1e-4)


def test_touching_the_seabed_ends_the_episode_with_the_collision_penalty():
    """Started 5 cm above the seabed (the hull's radius is about 9.5 cm): the first step is a collision."""
    low = mj.make(ENV, altitude_range=(0.05, 0.06), start_altitude_error=0.0)
    state = jax.jit(low.reset)(jax.random.PRNGKey(0))
    state = jax.jit(low.step)(state, jnp.zeros(low.action_size))
    assert float(state.metrics["collision"]) == 1.0 and float(state.done) == 1.0
    assert float(state.metrics["clearance"]) < 0
    assert float(state.metrics["reward/collision"]) == -low.config.reward.collision
    assert float(state.metrics["window_error"]) == low.config.max_distance


def test_leaving_the_transect_line_ends_the_episode():
    """With a corridor of 1 m, full rudder takes the vehicle off the line: a failure."""
    narrow = mj.make(ENV, max_cross_track=1.0)
    state = jax.jit(narrow.reset)(jax.random.PRNGKey(0))
    step = jax.jit(narrow.step)
    for i in range(100):
        state = step(state, jnp.array([1.0, 0.0, 0.5]))
        if float(state.done):
            break
    assert 1.0 < float(state.metrics["cross_track_error"]) < 1.5 and float(state.metrics["collision"]) == 0
    assert float(state.metrics["window_error"]) == narrow.config.max_distance


def test_the_classical_autopilot_on_the_altimeter_follows_the_terrain(env, tmp_path):
    """The torpedo autopilot reading the task's observation (its depth error: the measured altitude's)
    holds the altitude over 16 episodes without touching the seabed; the plot shows it from the side
    over the blocks."""
    out = rollout_controller(env, torpedo_autopilot(env, TorpedoAutopilotConfig(depth_gain=0.8)), 16, seed=5)
    window = np.asarray(env.error_window(out["time"]))
    assert np.mean(out["error"][:, window]) < 0.2
    assert np.max(out["collision"]) == 0 and np.max(out["done"]) == 0
    # the reference is the commanded altitude over the block below the vehicle
    x, z = out["position"][..., 0], out["position"][..., 2]
    tops = out["layout"][:, :, 2] + out["layout_size"][None, :, 2]
    below = np.take_along_axis(tops, np.clip(np.floor((x - FIRST_BLOCK_X) / BLOCK_LENGTH).astype(int), 0, 31), axis=1)
    np.testing.assert_allclose(out["error"], np.abs(out["target"][..., 2] - z), atol=1e-4)
    np.testing.assert_allclose(out["target"][..., :2], out["position"][..., :2], atol=1e-5)
    commanded = out["target"][..., 2] - below  # the altitude set-point, the same all episode
    assert np.all(np.ptp(commanded, axis=1) < 1e-4)
    assert np.all((commanded >= env.config.altitude_range[0] - 1e-4) & (commanded <= env.config.altitude_range[1] + 1e-4))
    assert out["layout_box"].all()
    assert plot_paths(out, "terrain", tmp_path / "paths.png").stat().st_size > 10_000
    # what an evaluation writes of the sonar (its 8 beams looking ahead at the seabed): the range
    # images and the trace its video draws (the beams' echoes, `render.SonarTrace`)
    from marinejax.train.evaluate import _sonar_trace, _write_sonar

    files = _write_sonar(env, out, "terrain", tmp_path)
    saved = np.load(files["ranges"])
    np.testing.assert_allclose(saved["ranges"], out["sonar"], atol=1e-5)
    assert saved["ranges"].shape == (16, env.config.episode_length, 8) and "intensity" not in saved
    trace = _sonar_trace(env, out, episode=0)
    assert trace.hit.mean() > 0.5 and trace.intensity is None  # the seabed ahead echoes
    np.testing.assert_array_equal(trace.hit, out["sonar"][0] < env.config.sensors.sonar.max_range)


def test_the_terrain_autopilot_anticipates_the_seabed_the_sonar_sees(env):
    """The autopilot blending the altitude error over the sonar's echoes ahead into its depth error
    (`controllers`, "terrain"): tuning runs the grid of weights in one call; weight 0 is the
    autopilot's depth loop alone, and weighting the seabed ahead lowers the error by a third or more;
    a task without the field is refused."""
    from marinejax.controllers import TUNING_GRIDS, make_controller, tune

    config, errors = tune("terrain", env, episodes=8)
    assert set(errors) == set(TUNING_GRIDS["terrain"][1]) and config.depth_gain == 0.8
    assert config.seabed_ahead > 0 and errors[config.seabed_ahead] < 0.67 * errors[0.0] and errors[0.0] < 0.3
    with pytest.raises(UserError, match="'lookahead' true"):
        make_controller("terrain", mj.make("Remus100-Autopilot"))
    with pytest.raises(UserError, match="'seabed_ahead'"):
        torpedo_autopilot(mj.make("Remus100-Autopilot"), TorpedoAutopilotConfig(seabed_ahead=0.3))
    with pytest.raises(UserError, match="'seabed_ahead' must be within"):
        TorpedoAutopilotConfig(seabed_ahead=1.5)


def test_the_autopilot_policy_can_start_it():
    """The observation extends the autopilot's: every field of the autopilot's is in terrain
    following's with its size, so `--ppo init_from=Remus100-Autopilot` can start it; the seabed ahead,
    the altimeter's and the sonar's fields are new (first-layer weights 0)."""
    from marinejax.train.ppo import input_rows

    source, env = mj.make("Remus100-Autopilot"), mj.make(ENV)
    rows = input_rows(source, env, "Remus100-Autopilot")
    f = env.observation_fields()
    new = np.nonzero(rows < 0)[0]
    np.testing.assert_array_equal(new, np.r_[f["altitude_error_ahead"].start:f["distance_ahead"].stop,
                                             f["altimeter"].start:f["sonar"].stop])


def test_lookahead_observes_the_seabed_the_sonar_sees_ahead_and_the_smooth_reward_its_profile():
    """With `lookahead`, two fields after the autopilot's: the altitude error over the sonar's echoes
    (the set-point minus the origin's height over the block where they land) and how far ahead they
    lie; with `smooth_reward`, the altitude terms about the profile through the blocks' centres
    (linear between them), the statistics still about the block below."""
    from marinejax.envs.base import distance_terms
    from marinejax.envs.terrain_following import block_centres, profile_z, seabed_z

    env = mj.make(ENV, smooth_reward=True, sensors={"sonar": {"ideal": True}})
    f = env.observation_fields()
    plain = mj.make(ENV, lookahead=False).observation_fields()
    assert (f["altitude_error_ahead"].start, f["distance_ahead"].start) == (plain["last_action"].stop, plain["last_action"].stop + 1)
    assert "altitude_error_ahead" not in plain and f["sonar"].stop == plain["sonar"].stop + 2
    states = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(1), 16))
    states = jax.jit(jax.vmap(env.step))(states, jnp.zeros((16, env.action_size)))
    task, q = states.info["task"], np.asarray(states.pipeline_state.physics.data.qpos)
    x, z = q[:, 0], q[:, 2]
    distance = np.asarray(states.obs[:, f["distance_ahead"]])[:, 0]
    assert np.all((distance > 3.0) & (distance < 15.0))  # 20° down from 1.5-3 m over a seabed of 20 % slopes
    # the echoes, from the ranges along the fan's beams turned to the world: on the seabed (frames right)
    sonar = env.plant.scene_sensors.sensors["sonar"]
    rot = np.asarray(jax.vmap(quat_to_mat)(q[:, 3:7]))
    ranges = np.asarray(states.info["scene_sensors"]["sonar"].reading.ranges)
    echoes = (q[:, None, :3] + np.einsum("nij,j->ni", rot, np.asarray(sonar.mount))[:, None]
              + ranges[..., None] * np.einsum("nij,bj->nbi", rot, np.asarray(sonar.directions[:, 0])))
    below = np.asarray(jax.vmap(seabed_z)(task.tops, jnp.asarray(echoes[..., 0])))
    edge = np.abs(((echoes[..., 0] - FIRST_BLOCK_X) / BLOCK_LENGTH + 0.5) % 1.0 - 0.5) * BLOCK_LENGTH
    assert (edge > 0.05).mean() > 0.8
    np.testing.assert_allclose(echoes[..., 2][edge > 0.05], below[edge > 0.05], atol=1e-3)
    # the field: the set-point minus the height over their mean, their mean distance along the heading
    expected = np.asarray(task.altitude) - (z - echoes[..., 2].mean(axis=1))
    np.testing.assert_allclose(np.asarray(states.obs[:, f["altitude_error_ahead"]])[:, 0], expected, atol=1e-4)
    heading = rot[:, :2, 0] / np.linalg.norm(rot[:, :2, 0], axis=1, keepdims=True)
    np.testing.assert_allclose(distance, np.einsum("nbi,ni->nb", echoes[..., :2] - q[:, None, :2], heading).mean(axis=1), atol=1e-4)
    # the smooth reward: the profile through the blocks' centres
    centres = block_centres(32)
    tops = np.asarray(task.tops)
    np.testing.assert_allclose(np.asarray(profile_z(task.tops[0], jnp.asarray(centres), jnp.asarray(centres[3:5]))), tops[0, 3:5], atol=1e-6)
    np.testing.assert_allclose(float(profile_z(task.tops[0], jnp.asarray(centres), jnp.asarray(centres[3] + 1.0))),
                               0.75 * tops[0, 3] + 0.25 * tops[0, 4], atol=1e-5)
    e = np.abs(np.asarray(jax.vmap(profile_z, (0, None, 0))(task.tops, jnp.asarray(centres), jnp.asarray(x))) + np.asarray(task.altitude) - z)
    r = env.config.reward
    np.testing.assert_allclose(np.asarray(states.metrics["reward/position"]), r.position * np.asarray(distance_terms(e, r)["position"]), rtol=1e-4)
    np.testing.assert_allclose(np.asarray(states.metrics["position_error"]),
                               np.abs(np.asarray(jax.vmap(seabed_z)(task.tops, jnp.asarray(x))) + np.asarray(task.altitude) - z), atol=1e-4)
    assert np.max(np.abs(e - np.asarray(states.metrics["position_error"]))) > 0.01  # they differ
    with pytest.raises(UserError, match="'lookahead' needs 'sensors.sonar.enabled'"):
        mj.make(ENV, lookahead=True, sensors={"sonar": {"enabled": False}})


def test_bad_settings_are_refused():
    with pytest.raises(UserError, match="'segments' must be 1"):
        mj.make(ENV, segments=2)
    with pytest.raises(UserError, match="'sensors.altimeter.enabled' must be true"):
        mj.make(ENV, sensors={"altimeter": {"enabled": False}})
    with pytest.raises(UserError, match="altitude_range"):
        mj.make(ENV, altitude_range=(3.0, 1.0))
    assert "Remus100-TerrainFollowingDisturbed" in mj.list_envs()
    assert type(mj.make("BlueROV2-TerrainFollowing")).__name__ == "RovTerrainFollowing"  # the ROVs' class of the task


def test_under_a_current_the_speed_through_the_water_stays_within_its_range():
    disturbed = mj.make("Remus100-TerrainFollowingDisturbed")
    states = jax.jit(jax.vmap(disturbed.reset))(jax.random.split(jax.random.PRNGKey(1), 64))
    lo, hi = disturbed.config.speed_range
    current = np.asarray(states.pipeline_state.current.mean)
    drift = np.linalg.norm(current[:, :2], axis=1) + 2 * 2**0.5 * disturbed.config.current.ou_sigma
    speed = np.asarray(states.info["task"].speed)
    assert np.all(speed >= lo + drift - 1e-5) and np.all(speed <= hi - drift + 1e-5)
