"""The autopilot task of torpedo AUVs: set-points per segment, its errors, start and observation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.envs.base import heading_error
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler, quat_to_mat


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
        mj.make("Remus100-Autopilot", integral_time_constant=-1.0)
    with pytest.raises(UserError, match="settled"):
        mj.make("Remus100-Autopilot", settled=70.0)


def test_the_disturbed_variant_draws_the_fins_and_propeller_and_currents_up_to_half_a_metre_per_second():
    env = mj.make("Remus100-AutopilotDisturbed")
    c = env.config.randomization
    assert env.config.current.speed == (0.0, 0.5) and env.config.current.mode == "ou"
    # horizontal mean currents: a sinking one would be out of reach slow through the water
    assert env.config.current.max_elevation_deg == 0.0
    means = np.asarray(jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(1), 16)).pipeline_state.current.mean)
    assert np.abs(means[:, 2]).max() < 1e-6 and np.linalg.norm(means[:, :2], axis=1).max() > 0.2
    params = jax.vmap(env.plant.sample_params)(jax.random.split(jax.random.PRNGKey(0), 64))
    rudder, stern, propeller = params.actuators
    for fins in (rudder, stern):
        lift = np.asarray(fins.lift_scale)
        assert lift.shape == (64, 1) and np.all((lift >= c.fin_lift_scale[0]) & (lift <= c.fin_lift_scale[1])) and lift.std() > 0.05
        tau = np.asarray(fins.time_constant)
        assert np.all((tau >= c.fin_time_constant[0]) & (tau <= c.fin_time_constant[1]))
    scale = np.asarray(propeller.thrust_scale)
    assert np.all((scale >= c.propeller_thrust_scale[0]) & (scale <= c.propeller_thrust_scale[1])) and scale.std() > 0.02
    assert np.all((np.asarray(propeller.time_constant) >= c.propeller_time_constant[0]) & (np.asarray(propeller.time_constant) <= c.propeller_time_constant[1]))
    # nominal: the file's values, the scales 1
    nominal = mj.make("Remus100-Autopilot").plant.sample_params(jax.random.PRNGKey(0))
    assert float(nominal.actuators[0].lift_scale[0]) == 1.0 and float(nominal.actuators[2].thrust_scale) == 1.0
    assert float(nominal.actuators[2].time_constant) == pytest.approx(1.0)


def test_a_weaker_rudder_turns_the_vehicle_more_slowly():
    """The fin's lift scale enters its force: half the lift, about half the turn rate at the start of a turn."""
    env = mj.make("Remus100-Autopilot", current={"mode": "off"})
    nominal = env.plant.sample_params(jax.random.PRNGKey(0))
    weak = nominal.replace(actuators=(nominal.actuators[0].replace(lift_scale=nominal.actuators[0].lift_scale * 0.5),) + nominal.actuators[1:])

    def yaw_rate(params):
        s = env.reset(jax.random.PRNGKey(3), params)
        for _ in range(10):
            s = env.step(s, jnp.array([1.0, 0.0, 0.5]))
        return float(env.plant.vehicle_state(s.pipeline_state).angular_velocity[2])

    strong, half = yaw_rate(nominal), yaw_rate(weak)
    assert strong < -0.02 and 0.35 < half / strong < 0.65  # positive rudder turns to starboard (negative yaw rate)


def test_commands_beyond_the_range_are_clipped_and_a_non_finite_one_ends_the_episode(env):
    state = env.reset(jax.random.PRNGKey(0))
    over = env.step(state, jnp.array([5.0, -7.0, 3.0]))
    at = env.step(state, jnp.array([1.0, -1.0, 1.0]))
    np.testing.assert_array_equal(np.asarray(over.obs), np.asarray(at.obs))
    bad = env.step(state, jnp.array([0.0, jnp.nan, 0.5]))
    assert float(bad.done) == 1.0 and float(bad.metrics["nonfinite"]) == 1.0 and np.all(np.isfinite(np.asarray(bad.obs)))


def test_slow_segments_ask_only_what_the_vehicle_can_reach(env):
    """Below full_manoeuvre_speed U_f the depth step shrinks by (U/U_f)^4 and the heading step by (U/U_f)^2."""
    c = env.config
    tasks = jax.vmap(env._sample_task)(jax.random.split(jax.random.PRNGKey(3), 2000))
    speed = np.asarray(tasks.speed[:, 1])
    u = np.clip(speed / c.full_manoeuvre_speed, 0, 1)
    step = np.abs(np.diff(np.asarray(tasks.depth), axis=1))[:, 0]
    turn = np.abs(np.diff(np.asarray(tasks.heading), axis=1))[:, 0]
    assert np.all(step <= c.depth_step * u**4 + 1e-4) and np.all(turn <= c.heading_step * u**2 + 1e-5)
    slow, fast = speed < 0.6, speed >= 1.0
    assert step[slow].max() < 0.15 * c.depth_step and step[fast].max() > 0.9 * c.depth_step
    assert turn[slow].max() < 0.37 * c.heading_step and turn[fast].max() > 0.9 * c.heading_step


def _nose_up(degrees):
    """The attitude (quaternion) with the nose `degrees` up, heading 1 rad (FLU, z up: nose up is a
    negative Euler pitch, checked here on the body x axis)."""
    q = quat_from_euler(0.0, -np.radians(degrees), 1.0)
    assert float((quat_to_mat(q) @ jnp.array([1.0, 0.0, 0.0]))[2]) > 0, "a negative pitch should raise the nose"
    return q


def test_the_progress_term_pays_the_rate_the_depth_error_shrinks(env):
    """Nose 30° up at 1.2 m/s: the vehicle climbs at 0.6 m/s, which earns +0.6 under a set-point above
    it, −0.6 under one below (heading 1 rad: the climb is read in the world frame)."""
    state = env.reset(jax.random.PRNGKey(0))
    task, info = state.info["task"], state.info
    vs = env.plant.vehicle_state(state.pipeline_state)
    q = _nose_up(30.0)
    for offset, expected in ((2.0, 0.6), (-2.0, -0.6)):
        here = vs.replace(position=jnp.array([0.0, 0.0, float(task.depth[0]) - offset]), quaternion=q,
                          velocity=jnp.array([1.2, 0.0, 0.0]), angular_velocity=jnp.zeros(3))
        terms = env.reward_terms(here, info, jnp.zeros(env.action_size))
        assert float(terms["progress"]) == pytest.approx(expected, abs=1e-5)
    assert env.config.reward.progress == 1.0


def test_the_dive_term_charges_a_flight_path_shallower_than_the_classical_depth_loops(env):
    """Weighted, the dive term is −(sin θ_ref − the sine of the flight-path angle towards the
    set-point), θ_ref = min(0.1 rad/m × |e|, 0.5 rad) (the classical autopilot's depth loop), at any
    speed, and 0 on a path as steep or steeper; unweighted (the default) it is not a term at all."""
    state = env.reset(jax.random.PRNGKey(0))
    assert "dive" not in env.reward_terms(env.plant.vehicle_state(state.pipeline_state), state.info, jnp.zeros(env.action_size))
    dive = mj.make("Remus100-Autopilot", **{"reward.dive": 1.0})
    state = dive.reset(jax.random.PRNGKey(0))
    task, info = state.info["task"], state.info
    vs = dive.plant.vehicle_state(state.pipeline_state)
    q = _nose_up(10.0)
    climb = np.sin(np.radians(10.0))  # the flight-path angle's sine, nose 10° up
    # (set-point above by m, speed m/s): 2 m asks sin 0.2, 8 m the 0.5 rad limit, 1 m less than 10°
    cases = [((2.0, 1.2), np.sin(0.2) - climb), ((8.0, 1.2), np.sin(0.5) - climb), ((8.0, 0.6), np.sin(0.5) - climb),
             ((1.0, 1.2), 0.0), ((-2.0, 1.2), np.sin(0.2) + climb)]
    for (offset, speed), shortfall in cases:
        here = vs.replace(position=jnp.array([0.0, 0.0, float(task.depth[0]) - offset]), quaternion=q,
                          velocity=jnp.array([speed, 0.0, 0.0]), angular_velocity=jnp.zeros(3))
        terms = dive.reward_terms(here, info, jnp.zeros(dive.action_size))
        assert float(terms["dive"]) == pytest.approx(-shortfall, abs=1e-5), (offset, speed)


def test_in_a_current_the_set_points_are_those_the_nominal_task_asks_at_the_slowest_speed_through_the_water():
    """Disturbed: the speed set-points keep the speed through the water within speed_range whatever
    the heading (U ± c), the depth and heading changes are the nominal's at U − c with the weakest
    fins, and the start stays where it was placed, its errors to the first set-point shrunk alike.
    Nominal: the set-points as drawn."""
    disturbed, nominal = mj.make("Remus100-AutopilotDisturbed"), mj.make("Remus100-Autopilot")
    keys = jax.random.split(jax.random.PRNGKey(4), 64)
    c = disturbed.config
    lo, hi = c.speed_range
    for env in (disturbed, nominal):
        states = jax.jit(jax.vmap(env.reset))(keys)
        task = jax.tree.map(lambda a: np.asarray(a, np.float64), states.info["task"])
        drawn = jax.tree.map(lambda a: np.asarray(a, np.float64), jax.vmap(lambda k: env._sample_task(jax.random.split(k, 6)[1]))(keys))
        if env is nominal:
            for name in ("depth", "heading", "speed"):
                np.testing.assert_allclose(getattr(task, name), getattr(drawn, name), rtol=1e-6)  # as drawn (jitted apart: last bit)
            continue
        mean = np.asarray(states.pipeline_state.current.mean, np.float64)
        drift = np.linalg.norm(mean[:, :2], axis=1) + 2 * np.sqrt(2) * c.current.ou_sigma
        speed = lo + drift[:, None] + (drawn.speed - lo) * (hi - lo - 2 * drift[:, None]) / (hi - lo)
        np.testing.assert_allclose(task.speed, speed, rtol=1e-5)
        assert np.all(task.speed - drift[:, None] >= lo - 1e-5) and np.all(task.speed + drift[:, None] <= hi + 1e-5)
        u = np.clip((task.speed - drift[:, None]) * np.sqrt(c.randomization.fin_lift_scale[0]) / c.full_manoeuvre_speed, 0, 1)
        # the second segment's changes: the drawn fraction of the full step, at the fitted reach
        drawn_u = np.clip(drawn.speed / c.full_manoeuvre_speed, 0, 1)
        inside = lambda d: (d > c.depth_range[0] + 1e-3) & (d < c.depth_range[1] - 1e-3)  # noqa: E731 (not clipped to depth_range)
        free = inside(task.depth[:, 0]) & inside(task.depth[:, 1]) & inside(drawn.depth[:, 1])
        np.testing.assert_allclose(np.diff(task.depth)[free, 0], (np.diff(drawn.depth)[:, 0] * (u[:, 1] / drawn_u[:, 1]) ** 4)[free],
                                   atol=1e-4)
        np.testing.assert_allclose(np.diff(task.heading)[:, 0], np.diff(drawn.heading)[:, 0] * (u[:, 1] / drawn_u[:, 1]) ** 2, atol=1e-5)
        assert free.sum() > 48 and (u[:, 1] < drawn_u[:, 1] - 0.05).sum() > 16  # most episodes fitted, many asked less
        # the start is the drawn one; its depth and heading errors to the first set-point shrink by the reach
        vs = jax.vmap(env.plant.vehicle_state)(states.pipeline_state)
        z = np.asarray(vs.position[:, 2], np.float64)
        np.testing.assert_allclose((z - task.depth[:, 0])[free], ((z - drawn.depth[:, 0]) * (u[:, 0] / drawn_u[:, 0]) ** 4)[free], atol=1e-4)
        yaw_error = np.asarray(jax.vmap(heading_error)(vs.quaternion, jnp.asarray(task.heading[:, 0], jnp.float32)))
        drawn_yaw_error = np.asarray(jax.vmap(heading_error)(vs.quaternion, jnp.asarray(drawn.heading[:, 0], jnp.float32)))
        np.testing.assert_allclose(yaw_error, drawn_yaw_error * (u[:, 0] / drawn_u[:, 0]) ** 2, atol=1e-4)


def test_a_current_too_fast_for_the_speed_range_is_refused():
    with pytest.raises(UserError, match=r"'speed_range' \(0.8, 2.0\) must be wider than twice the current's fastest horizontal drift"):
        mj.make("Remus100-AutopilotDisturbed", speed_range=(0.8, 2.0))
    mj.make("Remus100-Autopilot", speed_range=(0.8, 2.0))  # no current: any range


def _best_climb_rate(vehicle, speed, net_weight):
    """m/s of steady climb of `vehicle` at `speed` m/s through still water, `net_weight` N heavier than
    neutral, over the last 10 s of a minute with the stern planes at either limit: the better one."""
    from marinejax.physics import initial_state, rollout

    h = vehicle.sys.hydro
    sys = vehicle.sys.replace(hydro=h.replace(volume=h.volume - net_weight / (1000.0 * 9.81)))
    rpm = 608.0 * speed  # straight flight: 2.51 m/s at 1525 rpm
    rates = []
    for stern in (-1.0, 1.0):
        commands = np.tile(np.array([0.0, stern, 2.0 * rpm / 1525.0 - 1.0], np.float32), (600, 1))
        traj = rollout(vehicle, commands, initial_state(vehicle, velocity=(speed, 0.0, 0.0), actuators=(0.0, 0.0, rpm)),
                       control_dt=0.1, substeps=2, sys=sys)
        z = np.asarray(traj.position[:, 2])
        rates.append((z[-1] - z[-101]) / 10.0)
    return max(rates)


def test_below_one_metre_per_second_the_stern_planes_cannot_hold_a_few_newtons_of_weight():
    """Why the disturbed autopilot still loses depth where the current leaves the REMUS slow through
    the water: the planes' lift goes as U², so 2 N of net weight (the randomization draws up to
    1.5 N, the disturbance up to 4 N) sinks it at 0.75 m/s whatever the planes do, and not at 1 m/s."""
    remus = mj.load_vehicle("remus100")
    assert _best_climb_rate(remus, 0.75, 2.0) < -0.01
    assert _best_climb_rate(remus, 1.0, 2.0) > 0.05


def test_training_evaluations_get_the_heading_and_speed_errors_over_the_window(env, run):
    """Each target's `window_<error>` sums over an episode to that error's mean over the evaluation
    window, as `marinejax eval` computes it, so a checkpoint can be chosen on all three targets."""
    _, (_, metrics, _, time) = run
    assert dict(env.targets) == {"position_error": 0.1, "heading_error_deg": 2.0, "speed_error": 0.05}
    assert set(env.targets) <= set(env.error_names)
    mask = np.asarray(env.error_window(np.asarray(time[0], np.float64)))
    assert 0 < mask.sum() < mask.size
    for name in ("heading_error_deg", "speed_error"):
        error = np.asarray(metrics[name], np.float64)
        summed = np.asarray(metrics[f"window_{name}"], np.float64).sum(axis=1)
        np.testing.assert_allclose(summed, error[:, mask].mean(axis=1), rtol=1e-4)
        assert summed.min() > 0
    assert np.asarray(metrics["window_error"]).max() < env.config.max_distance  # no episode ended early
