"""ROV docking in the rov_dock scene: where episodes start, and the docked and impact metrics, with
a scripted pilot (wrench mode) that docks and one that rams the station."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.errors import UserError
from marinejax.frames import quat_to_euler, quat_to_mat

ENV = mj.make("BlueROV2Heavy-Docking", action_mode="wrench")
SCALE = jnp.asarray(ENV.config.wrench_scale)


def _pilot(ram: bool):
    """Aligns with the station's axis 1.2 m in front of it, then flies in (or rams it at full force)."""

    def act(state):
        vs = ENV.plant.vehicle_state(state.pipeline_state)
        rot = quat_to_mat(vs.quaternion)
        lateral = jnp.linalg.norm(vs.position[1:])
        goal = jnp.where(lateral < 0.05, jnp.array([0.05, 0.0, 0.0]), jnp.array([-1.2, 0.0, 0.0]))
        force = jnp.clip(30.0 * (goal - vs.position), -20.0, 20.0) - 40.0 * (rot @ vs.velocity)
        force = jnp.where(ram & (lateral < 0.05), jnp.array([80.0, 0.0, 0.0]), force)
        torque = jnp.array([0.0, 0.0, -20.0 * quat_to_euler(vs.quaternion)[2] - 10.0 * vs.angular_velocity[2]])
        return jnp.concatenate([rot.T @ force, torque]) / SCALE

    return act


@jax.jit
def _episodes(keys, ram):
    def one(key):
        state = ENV.reset(key)
        start = ENV.plant.vehicle_state(state.pipeline_state)

        def body(s, _):
            s = ENV.step(s, _pilot(ram)(s))
            return s, (s.metrics["docked"], s.metrics["impact_force"], s.metrics["reward/impact"])

        return start, jax.lax.scan(body, state, None, length=ENV.config.episode_length)[1]

    return jax.vmap(one)(keys)


def test_episodes_start_at_rest_in_front_of_the_station_at_the_configured_distance():
    starts, _ = _episodes(jax.random.split(jax.random.PRNGKey(0), 4), False)
    c = ENV.config
    distance = np.hypot(starts.position[:, 0], starts.position[:, 1])
    assert np.all((distance >= c.start_distance[0]) & (distance <= c.start_distance[1]))
    bearing = np.arctan2(starts.position[:, 1], -starts.position[:, 0])
    assert np.all(np.abs(bearing) <= c.start_bearing) and np.all(np.abs(starts.position[:, 2]) <= c.start_depth)
    assert not np.any(np.asarray(starts.velocity))


def test_a_pilot_that_aligns_first_docks_gently_and_one_that_rams_is_counted():
    keys = jax.random.split(jax.random.PRNGKey(0), 2)
    _, (docked, impact, reward) = _episodes(keys, False)
    assert np.all(np.asarray(docked[:, -1]) == 1.0)  # docked, held for 1 s, at the end of every episode
    assert float(impact.max()) < ENV.config.impact_threshold and float(reward.min()) == 0.0
    _, (docked, impact, reward) = _episodes(keys, True)
    assert float(impact.max()) > 2 * ENV.config.impact_threshold  # 80 N into the back bars
    assert float(reward.min()) < -1.0


def test_docking_needs_a_scene_with_contacts():
    with pytest.raises(UserError, match="needs a scene with contacts"):
        mj.make("BlueROV2-Docking", scene="open_water")
