"""Sensor models and the sensor observation mode: noise statistics measured from long samples against
the configured parameters, update rates, latencies, and what a sensor-mode policy sees."""

import dataclasses
import math
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax
from marinejax.errors import UserError
from marinejax.frames import quat_from_euler, quat_to_euler
from marinejax.physics import VehicleState
from marinejax.plant.sensors import SensorConfig, SensorSuite

DT = 0.05
G = 9.81
STEPS = 400  # 20 s per sequence
SEQUENCES = 256
CFG = SensorConfig()
IDEAL = {f"sensors.{s}.ideal": True for s in ("imu", "depth", "attitude", "dvl", "position_fix")}


def _state(t):
    """Level vehicle at yaw 0.3 rad moving at a constant 0.5 m/s along body x (world velocity constant)."""
    yaw = 0.3
    v_world = 0.5 * jnp.array([math.cos(yaw), math.sin(yaw), 0.0])
    return VehicleState(position=jnp.array([1.0, -2.0, -5.0]) + t * v_world, quaternion=quat_from_euler(0.0, 0.0, yaw),
                        velocity=jnp.array([0.5, 0.0, 0.0]), angular_velocity=jnp.zeros(3), actuators=jnp.zeros(6))


@pytest.fixture(scope="module")
def samples():
    """Measurements (and sensor states) of SEQUENCES independent episodes of STEPS steps each."""
    suite = SensorSuite(CFG, DT, G)

    def episode(key):
        k_p, k_i, k_s = jax.random.split(key, 3)
        state, m0 = suite.init(k_i, suite.sample_params(k_p), _state(0.0))

        def body(state, xs):
            i, k = xs
            state, m = suite.step(state, _state(i * DT), k)
            return state, (m, state.gyro_bias, state.accel_bias, state.yaw_drift, state.params.depth_offset)

        return jax.lax.scan(body, state, (jnp.arange(1, STEPS + 1), jax.random.split(k_s, STEPS)))[1]

    out = jax.jit(jax.vmap(episode))(jax.random.split(jax.random.PRNGKey(0), SEQUENCES))
    return jax.tree.map(np.asarray, out)


def test_imu_white_noise_and_turn_on_bias(samples):
    m, gyro_bias, accel_bias, _, _ = samples
    gyro_noise = m.gyro - gyro_bias  # the vehicle does not rotate
    np.testing.assert_allclose(gyro_noise.std(), CFG.imu.gyro_noise, rtol=0.02)
    assert abs(gyro_noise.mean()) < 0.02 * CFG.imu.gyro_noise
    # specific force: a level vehicle in uniform motion measures +g along body z
    f_noise = m.specific_force - accel_bias - np.array([0.0, 0.0, G])
    np.testing.assert_allclose(f_noise.std(), CFG.imu.accel_noise, rtol=0.02)
    assert np.abs(f_noise.mean(axis=(0, 1))).max() < 0.05 * CFG.imu.accel_noise
    # turn-on biases: std across episodes
    np.testing.assert_allclose(gyro_bias[:, 0].std(), CFG.imu.gyro_bias, rtol=0.15)
    np.testing.assert_allclose(accel_bias[:, 0].std(), CFG.imu.accel_bias, rtol=0.15)


def test_bias_random_walks_grow_with_the_square_root_of_time(samples):
    _, gyro_bias, accel_bias, yaw_drift, _ = samples
    for series, walk in ((gyro_bias, CFG.imu.gyro_bias_walk), (accel_bias, CFG.imu.accel_bias_walk)):
        growth = series - series[:, :1]  # change since the first step
        for steps in (100, 399):
            expected = walk * math.sqrt((steps) * DT)
            np.testing.assert_allclose(growth[:, steps].std(), expected, rtol=0.1)
    for steps in (100, 399):
        np.testing.assert_allclose(yaw_drift[:, steps].std(), CFG.attitude.yaw_drift * math.sqrt((steps + 2) * DT), rtol=0.1)


def test_attitude_noise_and_drift(samples):
    m, _, _, yaw_drift, _ = samples
    euler = np.asarray(jax.vmap(jax.vmap(quat_to_euler))(m.quaternion))
    np.testing.assert_allclose(euler[..., 0].std(), CFG.attitude.roll_pitch_noise, rtol=0.03)
    np.testing.assert_allclose(euler[..., 1].std(), CFG.attitude.roll_pitch_noise, rtol=0.03)
    yaw_error = euler[..., 2] - 0.3 - yaw_drift
    np.testing.assert_allclose(yaw_error.std(), CFG.attitude.yaw_noise, rtol=0.03)


def test_depth_offset_noise_resolution_and_rate(samples):
    m, _, _, _, offset = samples
    true_depth = 5.0  # z = -5 all the time
    err = m.depth - true_depth - offset[:, :1]
    res = CFG.depth.resolution
    np.testing.assert_allclose(np.round(m.depth / res) * res, m.depth, atol=1e-6)  # quantised
    np.testing.assert_allclose(err.std(), math.sqrt(CFG.depth.noise**2 + res**2 / 12), rtol=0.05)
    assert abs(err.mean()) < 2e-4
    # offsets uniform in ±offset: std offset/√3
    np.testing.assert_allclose(offset[:, 0].std(), CFG.depth.offset / math.sqrt(3), rtol=0.15)
    assert np.abs(offset).max() <= CFG.depth.offset


def test_dvl_noise_proportional_to_speed_rate_and_dropouts(samples):
    m = samples[0]
    period = round(1 / (CFG.dvl.rate_hz * DT))
    assert period == 2
    new = m.dvl_new
    # updates only every `period` steps, at one phase per episode; dropouts remove about 2 %
    assert not np.any(new[:, :-1] & new[:, 1:])
    np.testing.assert_allclose(new.mean(), (1 - CFG.dvl.dropout) / period, rtol=0.05)
    # between updates the value is held
    held = ~new[:, 1:]
    np.testing.assert_array_equal(m.dvl[:, 1:][held], m.dvl[:, :-1][held])
    std = CFG.dvl.noise_fraction * 0.5 + CFG.dvl.noise_floor
    err = m.dvl[new] - np.array([0.5, 0.0, 0.0])
    np.testing.assert_allclose(err.std(axis=0), std, rtol=0.05)


def test_position_fix_rate_latency_and_noise(samples):
    m = samples[0]
    period = round(1 / (CFG.position_fix.rate_hz * DT))
    delay = round(CFG.position_fix.latency / DT)
    new = m.fix_new
    np.testing.assert_allclose(new.mean(), 1 / period, rtol=0.02)
    new = new.copy()
    steps = np.arange(1, STEPS + 1)[None].repeat(SEQUENCES, 0)
    # the fix describes the position `delay` steps before it arrives
    late = np.asarray(jax.vmap(jax.vmap(lambda i: _state(i * DT).position))(jnp.asarray(steps - delay)))
    now = np.asarray(jax.vmap(jax.vmap(lambda i: _state(i * DT).position))(jnp.asarray(steps)))
    new[:, :10] = False  # before `delay` steps the fix describes the start
    err_late, err_now = (m.fix - late)[new], (m.fix - now)[new]
    np.testing.assert_allclose(err_late.std(axis=0), CFG.position_fix.noise, rtol=0.05)
    assert np.abs(err_late.mean(axis=0)).max() < 0.05 * CFG.position_fix.noise
    # a fix read as current lags by delay · dt · 0.5 m/s along the motion
    lag = np.linalg.norm(err_now.mean(axis=0))
    np.testing.assert_allclose(lag, delay * DT * 0.5, rtol=0.05)


def test_acoustic_fix_noise_grows_with_range_and_a_gps_fix_needs_the_surface():
    """range_noise: std per axis = noise + range_noise × slant range to the beacon; surface_only: no
    fix below surface_depth (the launch fix excepted), fixes again at the surface."""
    cfg = dataclasses.replace(CFG, position_fix=dataclasses.replace(CFG.position_fix, rate_hz=20.0, latency=0.0,
                                                                     range_noise=0.01, beacon=(0.0, 0.0, 0.0)))
    suite = SensorSuite(cfg, DT, G)

    def fixes(depth, key):
        vs = VehicleState(position=jnp.array([0.0, 0.0, -depth]), quaternion=quat_from_euler(0.0, 0.0, 0.0),
                          velocity=jnp.zeros(3), angular_velocity=jnp.zeros(3), actuators=jnp.zeros(6))
        k_p, k_i, k_s = jax.random.split(key, 3)
        state, _ = suite.init(k_i, suite.sample_params(k_p), vs)
        return jax.lax.scan(lambda st, k: suite.step(st, vs, k), state, jax.random.split(k_s, 200))[1]

    for depth in (10.0, 100.0):
        m = jax.jit(jax.vmap(lambda k: fixes(depth, k)))(jax.random.split(jax.random.PRNGKey(1), 32))
        err = np.asarray(m.fix)[np.asarray(m.fix_new)] - np.array([0.0, 0.0, -depth])
        np.testing.assert_allclose(err.std(axis=0), CFG.position_fix.noise + 0.01 * depth, rtol=0.05)
    gps = SensorSuite(dataclasses.replace(CFG, position_fix=dataclasses.replace(CFG.position_fix, rate_hz=20.0, surface_only=True)), DT, G)

    def gps_fixes(depth):
        vs = VehicleState(position=jnp.array([0.0, 0.0, -depth]), quaternion=quat_from_euler(0.0, 0.0, 0.0),
                          velocity=jnp.zeros(3), angular_velocity=jnp.zeros(3), actuators=jnp.zeros(6))
        state, first = gps.init(jax.random.PRNGKey(0), gps.sample_params(jax.random.PRNGKey(1)), vs)
        return first.fix_new, jax.lax.scan(lambda st, k: gps.step(st, vs, k), state, jax.random.split(jax.random.PRNGKey(2), 50))[1].fix_new

    launch, deep = gps_fixes(5.0)
    assert bool(launch) and not np.any(np.asarray(deep))
    assert np.all(np.asarray(gps_fixes(0.2)[1]))
    with pytest.raises(UserError, match="beacon"):
        marinejax.make("Remus100-Autopilot", sensors={"position_fix": {"beacon": (0.0, float("nan"), 0.0)}})


@pytest.mark.parametrize("section, key, value", [
    ("dvl", "noise_floor", -0.001), ("imu", "gyro_noise", float("nan")), ("depth", "rate_hz", 0.0),
    ("position_fix", "latency", float("inf")), ("dvl", "dropout", 1.0), ("latency", "observation", -1),
])
def test_bad_sensor_parameters_are_user_errors(section, key, value):
    with pytest.raises(UserError, match=f"sensors.{section}.{key}"):
        dataclasses.replace(getattr(CFG, section), **{key: value})


def test_bad_sensor_parameter_on_the_command_line_is_one_line_and_exit_2(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "marinejax.cli", "train", "BlueROV2-StationKeeping", "--env", "observation_mode=sensors",
         "--env", "sensors.dvl.noise_floor=-0.1", "--run-dir", str(tmp_path / "run")],
        capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 2
    lines = [line for line in proc.stderr.strip().splitlines() if line]
    assert len(lines) == 1 and "sensors.dvl.noise_floor" in lines[0] and "-0.1" in lines[0], proc.stderr
    with pytest.raises(UserError, match="observation_mode"):
        marinejax.make("BlueROV2-StationKeeping", observation_mode="camera")


# --- the env in sensor mode -------------------------------------------------------------------
ENV = "BlueROV2Heavy-CircleTracking"
EPISODES, HORIZON = 4, 60


def _rollout(env, actions, key=jax.random.PRNGKey(5)):
    """Observations, position errors and exact positions over HORIZON steps of EPISODES episodes."""

    def episode(k, acts):
        def body(s, a):
            s = env.step(s, a)
            return s, (s.obs, s.metrics["position_error"], env.plant.vehicle_state(s.pipeline_state).position)

        return jax.lax.scan(body, env.reset(k), acts)[1]

    return jax.tree.map(np.asarray, jax.jit(jax.vmap(episode))(jax.random.split(key, EPISODES), actions))


@pytest.fixture(scope="module")
def actions():
    env = marinejax.make(ENV)
    return 0.4 * jax.random.uniform(jax.random.PRNGKey(1), (EPISODES, HORIZON, env.action_size), minval=-1, maxval=1)


@pytest.fixture(scope="module")
def exact_run(actions):
    return _rollout(marinejax.make(ENV), actions)


@pytest.fixture(scope="module")
def sensor_run(actions):
    return _rollout(marinejax.make(ENV, observation_mode="sensors"), actions)


def test_ideal_sensors_give_the_exact_observation(actions, exact_run):
    obs, err, pos = _rollout(marinejax.make(ENV, observation_mode="sensors", **IDEAL), actions)
    np.testing.assert_array_equal(obs, exact_run[0])
    np.testing.assert_array_equal(err, exact_run[1])


def test_sensor_observation_contains_no_exact_state_component(exact_run, sensor_run):
    env = marinejax.make(ENV)
    n_act = env.action_size
    obs_exact, obs_sens = exact_run[0], sensor_run[0]
    # the last action (policy's own) sits before the 4 integral components; everything else is measured
    state_part = np.r_[0 : obs_exact.shape[-1] - 4 - n_act, obs_exact.shape[-1] - 4 : obs_exact.shape[-1]]
    differs = np.abs(obs_sens - obs_exact)[..., state_part] > 1e-7
    assert differs[:, 1:].mean(axis=(0, 1)).min() > 0.9, differs.mean(axis=(0, 1))
    actions_part = slice(obs_exact.shape[-1] - 4 - n_act, obs_exact.shape[-1] - 4)
    np.testing.assert_array_equal(obs_sens[..., actions_part], obs_exact[..., actions_part])
    # the physics does not see the sensors: same actions, same motion
    np.testing.assert_array_equal(sensor_run[2], exact_run[2])


@pytest.mark.parametrize("latency", [1, pytest.param(3, marks=pytest.mark.slow)])
def test_observation_latency_shifts_the_observation_by_exactly_that_many_steps(actions, sensor_run, latency):
    obs, _, pos = _rollout(marinejax.make(ENV, observation_mode="sensors", **{"sensors.latency.observation": latency}), actions)
    np.testing.assert_array_equal(obs[:, latency:], sensor_run[0][:, :-latency])
    np.testing.assert_array_equal(pos, sensor_run[2])


def test_action_latency_delays_the_thrusters_by_exactly_that_many_steps(actions, sensor_run):
    latency = 2
    delayed = _rollout(marinejax.make(ENV, observation_mode="sensors", **{"sensors.latency.action": latency}), actions)
    shifted = jnp.concatenate([jnp.zeros_like(actions[:, :latency]), actions[:, :-latency]], axis=1)
    reference = _rollout(marinejax.make(ENV, observation_mode="sensors"), shifted)
    np.testing.assert_array_equal(delayed[2], reference[2])
    assert np.abs(delayed[2] - sensor_run[2]).max() > 1e-3


def test_randomized_sensors_draw_latency_and_noise_per_episode():
    env = marinejax.make(ENV, observation_mode="sensors", **{"sensors.randomization.enabled": True})
    states = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 64))
    p = jax.tree.map(np.asarray, states.info["sensors"].params)
    assert set(p.observation_latency) == {0, 1, 2} and set(p.action_latency) == {0, 1, 2}
    assert p.noise_scale.min() >= 0.5 and p.noise_scale.max() <= 2.0 and p.noise_scale.std() > 0.2
    assert states.obs.shape == (64, env.observation_size)
