"""ROV terrain following: a reference moving along the transect over the terrain scene's seabed, the
altitude seen only through the altimeter, the hull touching the seabed ending the episode, and the PID
on the task's observation holding the altitude."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.controllers import pid_controller
from marinejax.envs import RovTerrainFollowing, TerrainFollowing
from marinejax.envs.base import heading_error
from marinejax.envs.terrain_following import seabed_z
from marinejax.errors import UserError
from marinejax.statistics import rollout_controller, summarize

ENV = "BlueROV2Heavy-TerrainFollowing"


@pytest.fixture(scope="module")
def env():
    return mj.make(ENV)


def test_one_task_name_with_a_class_per_vehicle_kind_and_bad_settings_named():
    assert isinstance(mj.make(ENV), RovTerrainFollowing) and isinstance(mj.make("BlueROV2-TerrainFollowingDisturbed"), RovTerrainFollowing)
    assert type(mj.make("Remus100-TerrainFollowing")) is TerrainFollowing
    with pytest.raises(UserError, match="'sensors.altimeter.enabled' must be true"):
        mj.make(ENV, **{"sensors.altimeter.enabled": False})
    with pytest.raises(UserError, match="'speed_range' must be > 0"):
        mj.make(ENV, speed_range=(0.0, 0.5))
    with pytest.raises(UserError, match="needs blocks"):
        mj.make(ENV, scene="pillars", movable_geoms=("pillar0", "pillar1"))


def test_the_reference_moves_along_the_transect_and_the_vehicle_starts_at_rest_at_the_altitude(env):
    states = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 16))
    task = states.info["task"]
    vs = jax.vmap(env.plant.vehicle_state)(states.pipeline_state)
    ground = jax.vmap(seabed_z)(task.tops, vs.position[:, 0])
    altitude = np.asarray(vs.position[:, 2] - ground)
    assert np.all(np.abs(altitude - np.asarray(task.altitude)) <= env.config.start_altitude_error + 1e-5)
    assert np.all(np.asarray(vs.velocity) == 0) and np.ptp(np.asarray(task.speed)) > 0.1
    # 7.5 s in, the reference is speed x 7.5 m along +x, at the commanded altitude over the seabed below it
    info = {**jax.tree.map(lambda x: x[3], states.info), "time": jnp.asarray(7.5)}
    target = np.asarray(env.target_position(info))
    x = float(task.speed[3]) * 7.5
    np.testing.assert_allclose(target, [x, 0.0, float(seabed_z(task.tops[3], x)) + float(task.altitude[3])], rtol=1e-5)


def test_the_vertical_error_observed_is_the_measured_altitude_error():
    """With an ideal altimeter, level and heading along the transect, the observed vertical position
    error is the commanded minus the true altitude; the error (statistics) is its size."""
    ideal = mj.make(ENV, **{"sensors.altimeter.ideal": True, "sensors.sonar.ideal": True}, start_heading_error=0.0)
    state = jax.jit(ideal.reset)(jax.random.PRNGKey(4))
    state = jax.jit(ideal.step)(state, jnp.zeros(ideal.action_size))
    vs = ideal.plant.vehicle_state(state.pipeline_state)
    task = state.info["task"]
    true = float(vs.position[2] - seabed_z(task.tops, vs.position[0]))
    fields = ideal.observation_fields()
    up = np.asarray(state.obs[fields["up"]])
    assert up[2] > 0.999  # level enough that body z is world z
    assert float(state.obs[fields["position_error"]][2]) == pytest.approx(float(task.altitude) - true, abs=2e-3)
    assert float(state.metrics["position_error"]) == pytest.approx(abs(float(task.altitude) - true), abs=1e-5)
    np.testing.assert_allclose(state.obs[fields["reference_velocity"]], [float(task.speed), 0.0, 0.0], atol=2e-3)


def test_the_sharp_heading_term_only_where_weighted():
    """`reward.heading_precision` pays exp(−|heading error| / scale) about the transect's heading,
    weighted; unweighted (the default) the env has no such term, so its metrics keep their keys."""
    weighted = mj.make(ENV, **{"reward.heading_precision": 2.0, "reward.heading_precision_scale": 0.1})
    state = jax.jit(weighted.reset)(jax.random.PRNGKey(2))
    state = jax.jit(weighted.step)(state, jnp.zeros(weighted.action_size))
    yaw_error = float(heading_error(weighted.plant.vehicle_state(state.pipeline_state).quaternion, state.info["task"].yaw))
    assert 0.01 < abs(yaw_error) < math.radians(10.0)  # a start heading off the transect's, within start_heading_error
    assert float(state.metrics["reward/heading_precision"]) == pytest.approx(2.0 * math.exp(-abs(yaw_error) / 0.1), rel=1e-5)
    plain = mj.make(ENV)
    assert "reward/heading_precision" not in jax.jit(plain.step)(jax.jit(plain.reset)(jax.random.PRNGKey(2)), jnp.zeros(plain.action_size)).metrics


def test_touching_the_seabed_ends_the_episode():
    low = mj.make(ENV, altitude_range=(0.05, 0.06), start_altitude_error=0.0)
    state = jax.jit(low.reset)(jax.random.PRNGKey(0))
    state = jax.jit(low.step)(state, jnp.zeros(low.action_size))
    assert float(state.metrics["collision"]) == 1.0 and float(state.done) == 1.0 and float(state.metrics["clearance"]) < 0
    assert float(state.metrics["reward/collision"]) == -low.config.reward.collision


def test_the_pid_on_the_altimeter_follows_the_terrain_along_the_transect(env):
    """The PID reading the task's observation (its vertical error: the measured altitude's) over 8
    episodes: within 0.2 m of the commanded altitude on average after the first 10 s, never touching
    the seabed, keeping up with the reference along the transect and on the line."""
    out = rollout_controller(env, pid_controller(env), 8, seed=5)
    stats = summarize(env, out)
    window = np.asarray(env.error_window(out["time"]))
    assert stats["position_error_mean_m"] < 0.2 and stats["success_rate"] >= 0.75, stats
    assert np.max(out["collision"]) == 0 and np.max(out["done"]) == 0
    assert np.abs(out["along_track_error"][:, window]).mean() < 0.5 and out["cross_track_error"].max() < 0.5
    travelled = out["position"][:, -1, 0] - out["position"][:, 0, 0]
    assert travelled.min() > 0.2 * 50  # m: at least the slowest reference over most of the minute
