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
            return s, (s.metrics["docked"], s.metrics["impact_force"], s.metrics["reward/impact"], s.metrics["reward/docked"],
                       s.info["task"].hold)

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
    _, (docked, impact, reward, reward_docked, hold) = _episodes(keys, False)
    assert np.all(np.asarray(docked[:, -1]) == 1.0)  # docked, held for 1 s, at the end of every episode
    assert float(impact.max()) < ENV.config.impact_threshold and float(reward.min()) == 0.0
    # the docked term: the time held without a break over dock_hold, at most 1 (weight 1)
    c = ENV.config
    assert c.reward.docked == 1.0
    np.testing.assert_allclose(np.asarray(reward_docked), np.minimum(np.asarray(hold) / c.dock_hold, 1.0), atol=1e-6)
    ramp = np.asarray(reward_docked[0])
    first = int(np.argmax(ramp > 0))  # the first docked step earns one step's share, a held one 1
    assert ramp[first] == pytest.approx(c.control_dt / c.dock_hold) and ramp[-1] == 1.0
    _, (docked, impact, reward, _, _) = _episodes(keys, True)
    assert float(impact.max()) > 2 * ENV.config.impact_threshold  # 80 N into the back bars
    assert float(reward.min()) < -1.0


def test_docking_needs_a_scene_with_contacts():
    with pytest.raises(UserError, match="needs a scene with contacts"):
        mj.make("BlueROV2-Docking", scene="open_water")


def _at(position, yaw=0.0):
    from marinejax.physics import VehicleState

    return VehicleState(position=jnp.asarray(position, jnp.float32), quaternion=mj.frames.quat_from_euler(0.0, 0.0, yaw),
                        velocity=jnp.zeros(3), angular_velocity=jnp.zeros(3), actuators=jnp.zeros(ENV.vehicle.num_actuators))


def test_the_guide_advances_at_its_speed_slows_to_the_landing_point_and_waits_until_the_vehicle_is_lined_up():
    c = ENV.config
    dt = c.control_dt
    task = ENV._sample_task(jax.random.PRNGKey(0))
    # it starts at the start's projection on the axis, at most approach_distance in front
    assert float(ENV.fit_task(None, task, None, None, _at([-3.0, 2.0, 0.5])).guide) == pytest.approx(-3.0)
    assert float(ENV.fit_task(None, task, None, None, _at([-0.8, 2.0, 0.5])).guide) == pytest.approx(-c.approach_distance)
    step = lambda guide, *pose: float(ENV._next_guide(_at(*pose), task.replace(guide=jnp.float32(guide))))  # noqa: E731
    # far out, lined up: approach_speed; near the landing point guide_gain × the distance to its stop,
    # standoff in front of the landing point (a vehicle left behind the stop is led back to it)
    assert step(-3.0, [-3.0, 0.0, 0.0]) == pytest.approx(-3.0 + c.approach_speed * dt, abs=1e-6)
    assert step(-0.2, [-0.25, 0.01, 0.0]) == pytest.approx(-0.2 + c.guide_gain * (0.2 - c.standoff) * dt, abs=1e-6)
    assert step(-c.standoff, [-0.01, 0.0, 0.0]) == pytest.approx(-c.standoff)
    assert step(0.0, [0.01, 0.0, 0.0]) == pytest.approx(-c.standoff)
    # never more than guide_lead ahead of the vehicle (one left behind pulls it back)
    assert step(-1.0, [-2.0, 0.0, 0.0]) == pytest.approx(-2.0 + c.guide_lead, abs=1e-6)
    # beyond align_limit, sideways or by heading (0.5 rad × 0.3 m/rad), it waits approach_distance in
    # front (and leads a misaligned vehicle back out); halfway between the limits, halfway out
    assert step(-0.3, [-0.6, 0.2, 0.0]) == pytest.approx(-c.approach_distance, abs=1e-6)
    assert step(-0.3, [-0.6, 0.0, 0.0], 0.5) == pytest.approx(-c.approach_distance, abs=1e-6)
    assert step(-0.3, [-0.6, 0.0, 0.1]) == pytest.approx(-0.5 * c.approach_distance, abs=1e-5)
    np.testing.assert_allclose(np.asarray(ENV.guide(task.replace(guide=jnp.float32(-0.7)))), [-0.7, 0.0, 0.0])
    # the route through the guide: the straight distance on the axis, longer off it
    assert float(ENV.route_distance(_at([-2.0, 0.0, 0.0]), task.replace(guide=jnp.float32(-1.5)))) == pytest.approx(2.0, abs=1e-6)
    off = float(ENV.route_distance(_at([-0.6, 0.2, 0.0]), task.replace(guide=jnp.float32(-1.2))))
    assert off == pytest.approx(np.hypot(0.6, 0.2) + 1.2, abs=1e-5)


def test_the_observation_steers_to_the_guide_and_sees_the_landing_point():
    state = ENV.reset(jax.random.PRNGKey(3))
    vs = ENV.plant.vehicle_state(state.pipeline_state)
    fields = ENV.observation_fields()
    rot = np.asarray(quat_to_mat(vs.quaternion))
    guide = np.asarray(ENV.guide(state.info["task"]))
    np.testing.assert_allclose(np.asarray(state.obs[fields["position_error"]]), rot.T @ (guide - np.asarray(vs.position)), atol=1e-5)
    np.testing.assert_allclose(np.asarray(state.obs[fields["dock"]]), rot.T @ -np.asarray(vs.position), atol=1e-5)
    assert fields["dock"].stop == fields["integral_position"].start  # the task's fields, then the integral


def test_the_pid_flying_to_the_guide_docks_without_touching_the_station():
    from marinejax.controllers import pid_controller
    from marinejax.statistics import rollout_controller, summarize

    env = mj.make("BlueROV2Heavy-Docking")
    result = rollout_controller(env, pid_controller(env), episodes=4, seed=12345)
    assert summarize(env, result)["success_rate"] == 1.0  # docked, held 1 s, at the end of every episode
    assert result["impact_force"].max() == 0.0


@pytest.mark.parametrize("overrides, message", [
    ({"standoff": 0.1}, "config 'standoff' (0.1 m) must be below 'dock_inside' (0.1 m)"),
    ({"align_limit": 0.05}, "config 'align_limit' (0.05 m) must be above 'align_tolerance' (0.05 m)"),
])
def test_a_guide_that_could_not_dock_is_refused(overrides, message):
    import re

    with pytest.raises(UserError, match=re.escape(message)):
        mj.make("BlueROV2Heavy-Docking", **overrides)
