"""Obstacle avoidance: piles placed per episode where the task says, seen by the sonar in the MJX
scene, a collision measured against the vehicle's collision capsules that ends the episode."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax
from marinejax.controllers import pid_controller
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler

ENV = "BlueROV2Heavy-ObstacleAvoidance"


@pytest.fixture(scope="module")
def env():
    return marinejax.make(ENV)


@pytest.fixture(scope="module")
def resets(env):
    return jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 64))


def test_piles_are_placed_between_start_and_goal_and_the_scene_holds_them(env, resets):
    c = env.config
    task = resets.info["task"]
    start, goal, piles = (np.asarray(x) for x in (task.start, task.position, task.piles))
    axis = (goal - start)[:, :2]
    length = np.linalg.norm(axis, axis=1)
    assert np.all((length >= c.goal_distance[0]) & (length <= c.goal_distance[1]))
    axis /= length[:, None]
    rel = piles[:, :, :2] - start[:, None, :2]
    along = np.einsum("eij,ej->ei", rel, axis)
    across = np.abs(rel[..., 0] * axis[:, None, 1] - rel[..., 1] * axis[:, None, 0])
    used = slice(0, c.obstacles)
    assert np.all(along[:, used] >= c.clearance - 1e-4) and np.all(along[:, used] <= length[:, None] - c.clearance + 1e-4)
    assert np.all(across[:, used] <= c.field_width / 2 + 1e-4)
    assert np.all(np.linalg.norm(piles[:, c.obstacles:, :2], axis=-1) > 900)  # the rest parked
    # what the physics and the sensors see is the episode's layout
    np.testing.assert_array_equal(resets.info["params"].layout, task.piles)
    model, _ = env.plant.world(jax.tree.map(lambda x: x[0], resets.info["params"]), jax.tree.map(lambda x: x[0], resets.pipeline_state))
    np.testing.assert_allclose(np.asarray(model.geom_pos)[np.asarray(env.plant.sys.layout_ids)], piles[0])


def _with_pile_ahead(env, state, distance: float):
    """The episode with every pile parked but one, `distance` m ahead of the vehicle's CG, level at heading 0."""
    ps = state.pipeline_state
    qpos = ps.physics.data.qpos
    qpos = qpos.at[3:7].set(quat_from_euler(0.0, 0.0, 0.0))
    ps = ps.replace(physics=ps.physics.replace(data=ps.physics.data.replace(qpos=qpos, qvel=jnp.zeros_like(ps.physics.data.qvel))))
    task = state.info["task"]
    piles = task.piles.at[:, 0].add(2000.0).at[0].set(qpos[:3] + jnp.array([distance, 0.0, 0.0]))
    goal = qpos[:3] + jnp.array([2 * distance, 0.0, 0.0])  # behind the pile
    info = {**state.info, "task": task.replace(piles=piles, position=goal), "params": state.info["params"].replace(layout=piles)}
    return state.replace(pipeline_state=ps, info=info)


def test_the_sonar_sees_a_pile_ahead_and_ramming_it_ends_the_episode(env, resets):
    """A pile (radius 0.3 m) 5 m ahead of the CG, 4.75 m from the sonar: the two centre beams of 32
    (at azimuth a = ±2.1°, 10° down) read where they meet its circle, (4.75 cos a − sqrt(0.3² −
    (4.75 sin a)²)) / cos 10°;
    a PID flying straight to the goal behind it hits it: collision, done, the failure's window error,
    the penalty."""
    state = _with_pile_ahead(env, jax.tree.map(lambda x: x[0], resets), 5.0)
    step = jax.jit(env.step)
    pid = pid_controller(env)
    state = step(state, jnp.zeros(env.action_size))
    ranges = np.asarray(state.info["scene_sensors"]["sonar"].reading.ranges)
    a = np.radians(np.linspace(-65, 65, 32)[15:17])
    expected = (4.75 * np.cos(a) - np.sqrt(0.3**2 - (4.75 * np.sin(a)) ** 2)) / np.cos(np.radians(10.0))  # the ray is 10° down
    np.testing.assert_allclose(ranges[15:17], expected, atol=0.08)  # 4 x the sonar's noise
    assert np.all(ranges[:15] == 20.0) and np.all(ranges[17:] == 20.0)  # beside it, nothing
    act = jax.jit(pid.act)
    for _ in range(100):
        state = step(state, act((), state.obs, state.info)[0])
        if float(state.done):
            break
    assert float(state.done) == 1.0 and float(state.metrics["collision"]) == 1.0
    assert float(state.metrics["clearance"]) < 0
    assert float(state.metrics["window_error"]) == env.config.max_distance
    assert float(state.metrics["reward/collision"]) == -env.config.reward.collision


def test_clearance_is_the_gap_between_pile_and_collision_capsules(env):
    """The Heavy's collision capsules run along x at y = ±0.135 m from x = −0.11 to 0.13 m, radius
    0.13 m: a pile of radius r at (x, 0) ahead is sqrt((x − 0.13)² + 0.135²) − 0.13 − r away."""
    from marinejax.physics import VehicleState

    vs = VehicleState(position=jnp.zeros(3), quaternion=quat_from_euler(0.0, 0.0, 0.0), velocity=jnp.zeros(3),
                      angular_velocity=jnp.zeros(3), actuators=jnp.zeros(env.action_size))
    xs = np.array([0.5, 1.0, 2.0])
    piles = jnp.asarray(np.concatenate([np.stack([xs, np.zeros(3), np.zeros(3)], -1), np.full((9, 3), 1000.0)]), jnp.float32)
    gap = np.asarray(env.clearance(vs, piles))[:3]
    r = np.asarray(env._pile_radius)[:3]
    np.testing.assert_allclose(gap, np.sqrt((xs - 0.13) ** 2 + 0.135**2) - 0.13 - r, atol=1e-5)
    # turned 90°, the pile at (0, 1) is seen by the same capsules' ends
    turned = vs.replace(quaternion=quat_from_euler(0.0, 0.0, math.pi / 2))
    side = piles.at[0].set(jnp.array([0.0, 1.0, 0.0]))
    np.testing.assert_allclose(np.asarray(env.clearance(turned, side))[0], math.hypot(0.87, 0.135) - 0.13 - float(r[0]), atol=1e-5)


def test_bad_layouts_are_named():
    with pytest.raises(UserError, match="obstacles"):
        marinejax.make(ENV, obstacles=20)
    with pytest.raises(UserError, match="no geom 'pillar99'.*valid"):
        marinejax.make(ENV, movable_geoms=("pillar99",), obstacles=1)


def test_surfacing_ends_the_episode_in_failure(env, resets):
    """No free surface is modelled: a vehicle shallower than 0.5 m has left the water, a failure."""
    state = jax.tree.map(lambda x: x[0], resets)
    ps = state.pipeline_state
    shallow = ps.replace(physics=ps.physics.replace(data=ps.physics.data.replace(qpos=ps.physics.data.qpos.at[2].set(-0.3))))
    state = env.step(state.replace(pipeline_state=shallow), jnp.zeros(env.action_size))
    assert float(state.metrics["surfaced"]) == 1.0 and float(state.done) == 1.0 and float(state.metrics["collision"]) == 0.0


@pytest.mark.slow
def test_steering_on_the_sonar_avoids_the_piles_a_straight_flight_hits(env):
    """16 episodes: the PID flying straight at the goal ends most of them on a pile; the same PID
    steered by follow-the-gap on the sonar (`avoid`), having seen the piles only through the sonar,
    hits a third as many and reaches the goal more often (some of its detours take longer than 60 s)."""
    from marinejax.controllers import AvoidConfig, avoid_controller
    from marinejax.statistics import rollout_controller, summarize

    straight = summarize(env, rollout_controller(env, pid_controller(env), 16, seed=3))
    steered = summarize(env, rollout_controller(env, avoid_controller(env, AvoidConfig(safe_range=6.0)), 16, seed=3))
    assert straight["terminated_episodes"] >= 8 and steered["terminated_episodes"] <= 4, (straight, steered)
    assert steered["success_rate"] >= straight["success_rate"] + 0.25, (straight, steered)
