"""Every registered env: jit/vmap, shapes, finiteness over full episodes, rewards, resets, randomness."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
import marinejax.envs as E
from marinejax.control import run_steps, sequence_controller
from marinejax.plant.current import CurrentConfig, sample_current, step_current
from marinejax.physics import VehicleState
from marinejax.vehicle import vehicle_kind


def episode_fn(env):
    """jit(vmap) of a full episode under given actions (the one closed-loop rollout, open-loop
    controller): final state and, per step, obs, reward, done and all metrics."""

    def run(key, actions):
        state = env.reset(key)
        controller = sequence_controller(actions)
        final, _, out = run_steps(env, controller, state, controller.init(key), actions.shape[0],
                                  lambda s: (s.obs, s.reward, s.done, s.metrics))
        return final, out

    return jax.jit(jax.vmap(run))


# A Disturbed variant runs its task's code and more (currents, randomized physics, a disturbance):
# it stands for the plain one, except for one task per vehicle kind (station keeping, the autopilot);
# the BlueROV2's tracking tasks are the Heavy's with another vehicle file: its fast lemniscate stands for them.
# The Fast tracking variants are the tracking class with a faster trajectory config: one stands for
# all; the path-following tasks are one class over four paths: two stand for all; docking (contacts,
# the slowest step), obstacle avoidance and ROV terrain following (600 steps with a sonar): one ROV each.
@pytest.mark.parametrize("name", [n for n in E.list_envs() if n.endswith("Disturbed") and not any(
                                      k in n for k in ("Fast", "Following", "Docking", "Obstacle"))
                                  and not (n.startswith("BlueROV2-") and "Tracking" in n)]
                         + ["BlueROV2Heavy-StationKeeping", "Remus100-Autopilot",
                            "BlueROV2-LemniscateTrackingFastDisturbed", "Remus100-WaypointFollowingDisturbed", "Remus100-LemniscateFollowing",
                            "BlueROV2Heavy-DockingDisturbed", "BlueROV2-ObstacleAvoidanceDisturbed", "BlueROV2-TerrainFollowingDisturbed"])
def test_env_runs_a_full_episode_finite_under_random_and_extreme_actions(name):
    env = E.make(name)
    n = env.config.episode_length
    keys = jax.random.split(jax.random.PRNGKey(1), 4)
    rand = jax.random.uniform(jax.random.PRNGKey(2), (2, n, env.action_size), minval=-1, maxval=1)
    actions = jnp.concatenate([rand, jnp.ones((1, n, env.action_size)), -jnp.ones((1, n, env.action_size))])
    final, (obs, reward, done, metrics) = episode_fn(env)(keys, actions)
    assert obs.shape == (4, n, env.observation_size)
    assert np.all(np.isfinite(np.asarray(obs))) and np.all(np.isfinite(np.asarray(reward)))
    assert float(jnp.sum(metrics["nonfinite"])) == 0
    for key in ("position_error", "heading_error_deg", "reward/position", "reward/effort"):
        assert key in metrics
    # the full-throttle vehicles leave the work area or at least move a lot
    assert float(jnp.max(metrics["position_error"][2:])) > 0.5


@pytest.fixture(scope="module")
def sk():
    return E.make("BlueROV2Heavy-StationKeeping")


def at(position, yaw, n_thrusters=8, velocity=(0, 0, 0), angular_velocity=(0, 0, 0), roll=0.0):
    return VehicleState(
        position=jnp.asarray(position, jnp.float32),
        quaternion=mj.frames.quat_from_euler(roll, 0.0, yaw),
        velocity=jnp.asarray(velocity, jnp.float32),
        angular_velocity=jnp.asarray(angular_velocity, jnp.float32),
        actuators=jnp.zeros(n_thrusters),
    )


def test_station_reward_is_largest_at_zero_error(sk):
    state = sk.reset(jax.random.PRNGKey(0))
    task = state.info["task"]
    zero = jnp.zeros(8)
    reward_terms = jax.jit(lambda vs, a: sk.reward_terms(vs, state.info, a))

    def reward(vs, a=zero):
        terms = reward_terms(vs, a)
        return sum(getattr(sk.config.reward, k) * float(v) for k, v in terms.items())

    best = reward(at(task.position, task.yaw))
    w = sk.config.reward
    assert best == pytest.approx(w.position + w.precision + w.upright + w.heading + w.heading_precision, rel=1e-5)
    worse = [
        at(task.position + jnp.array([0.05, 0, 0]), task.yaw),
        at(task.position, task.yaw + 0.2),
        at(task.position, task.yaw, roll=0.2),
        at(task.position, task.yaw, angular_velocity=(0, 0, 0.3)),
    ]
    for vs in worse:
        assert reward(vs) < best
    assert reward(at(task.position, task.yaw), jnp.full(8, 0.5)) < best


def test_station_reward_terms_follow_their_formulas(sk):
    state = sk.reset(jax.random.PRNGKey(0))
    task = state.info["task"]
    d = 0.5
    vs, action = at(task.position + jnp.array([0.0, d, 0.0]), task.yaw + 0.3), jnp.full(8, 0.5)
    obs, terms, errors = sk.observe(vs, state.info, action), sk.reward_terms(vs, state.info, action), sk.errors(vs, state.info)
    w = sk.config.reward
    assert float(errors["position_error"]) == pytest.approx(d, rel=1e-5)
    assert float(terms["position"]) == pytest.approx(1 / (1 + (d / w.position_scale) ** 2), rel=1e-5)
    assert float(terms["precision"]) == pytest.approx(math.exp(-d / w.precision_scale), rel=1e-4)
    assert float(terms["heading"]) == pytest.approx((1 + math.cos(0.3)) / 2, rel=1e-5)
    assert float(terms["heading_precision"]) == pytest.approx(math.exp(-0.3 / w.heading_precision_scale), rel=1e-4)
    assert float(errors["heading_error_deg"]) == pytest.approx(math.degrees(0.3), rel=1e-4)
    assert float(terms["effort"]) == pytest.approx(-0.25, rel=1e-6)
    assert float(terms["smoothness"]) == pytest.approx(-0.25, rel=1e-6)  # last action was zero
    # observation: position error in the body frame; the target is d to the world +y of the vehicle
    yaw = float(task.yaw) + 0.3
    np.testing.assert_allclose(obs[:3], [d * math.sin(yaw) * -1, d * math.cos(yaw) * -1, 0.0], atol=1e-5)


@pytest.fixture(scope="module")
def sk_vmapped(sk):
    return jax.jit(jax.vmap(sk.reset)), jax.jit(jax.vmap(sk.step))


def test_same_seed_same_episode_different_seed_different(sk, sk_vmapped):
    reset, step = sk_vmapped
    keys = jnp.stack([jax.random.PRNGKey(5), jax.random.PRNGKey(5), jax.random.PRNGKey(6)])
    s = reset(keys)
    a = jnp.full((3, 8), 0.2)
    for _ in range(3):
        s = step(s, a)
    np.testing.assert_array_equal(np.asarray(s.obs[0]), np.asarray(s.obs[1]))
    assert not np.allclose(np.asarray(s.obs[0]), np.asarray(s.obs[2]))
    assert not np.allclose(np.asarray(s.info["task"].position[0]), np.asarray(s.info["task"].position[2]))


def test_training_wrapper_redraws_every_episode(sk):
    env = E.wrap_for_training(sk, episode_length=4)
    reset, step = jax.jit(env.reset), jax.jit(env.step)
    s = reset(jax.random.split(jax.random.PRNGKey(0), 2))
    targets = [np.asarray(s.info["task"].position)]
    truncations = []
    for _ in range(12):
        s = step(s, jnp.zeros((2, 8)))
        truncations.append(np.asarray(s.info["truncation"]))
        targets.append(np.asarray(s.info["task"].position))
    # an episode ends every 4 steps, truncated (bootstrappable), and the new one has a new target
    assert [int(t[0]) for t in truncations] == [0, 0, 0, 1] * 3
    episode_targets = [targets[0], targets[4], targets[8], targets[12]]
    for a, b in zip(episode_targets, episode_targets[1:]):
        assert not np.allclose(a, b)
    np.testing.assert_array_equal(targets[1], targets[3])  # constant within an episode
    assert int(s.info["steps"][0]) == 4 or int(s.info["steps"][0]) == 0


def test_fixed_episodes_start_the_same_episodes_whatever_the_keys(sk):
    # the training evaluations' env with ppo.fixed_eval_episodes: the same episodes every evaluation
    fixed = jax.jit(E.wrap_for_training(E.FixedEpisodes(sk, seed=7), episode_length=4).reset)
    plain = jax.jit(E.wrap_for_training(sk, episode_length=4).reset)
    k1, k2 = jax.random.split(jax.random.PRNGKey(0), 3), jax.random.split(jax.random.PRNGKey(1), 3)
    a = fixed(k1)
    np.testing.assert_array_equal(np.asarray(a.obs), np.asarray(fixed(k2).obs))
    # three different episodes, other ones from another seed; without it the keys decide
    assert len({tuple(np.round(p, 6)) for p in np.asarray(a.info["task"].position)}) == 3
    other = jax.jit(E.wrap_for_training(E.FixedEpisodes(sk, seed=8), episode_length=4).reset)(k1)
    assert not np.allclose(np.asarray(other.obs), np.asarray(a.obs))
    assert not np.allclose(np.asarray(plain(k1).obs), np.asarray(plain(k2).obs))


def test_domain_randomization_changes_parameters_and_dynamics():
    still = {"velocity": 0.0, "angular_velocity": 0.0, "tilt": 0.0}
    env = E.make("BlueROV2Heavy-StationKeeping", randomization={"enabled": True, "net_buoyancy": (-3.0, 3.0)}, reset=still)
    nominal = E.make("BlueROV2Heavy-StationKeeping")
    keys = jax.random.split(jax.random.PRNGKey(3), 16)
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    s = reset(keys)
    dyn = s.info["params"]
    assert np.std(np.asarray(dyn.mass)) > 0.1 and np.std(np.asarray(dyn.hydro.added_mass[:, 2])) > 0.5
    assert np.std(np.asarray(dyn.actuators[0].voltage)) > 0.3
    s_nom = jax.jit(jax.vmap(nominal.reset))(keys)
    np.testing.assert_allclose(np.asarray(s_nom.info["params"].mass), 13.5, rtol=1e-6)
    # passive sinking: the heavier (net weight W - B) a vehicle, the faster it sinks
    position = jax.vmap(lambda ps: env.plant.vehicle_state(ps).position)
    z0 = np.asarray(position(s.pipeline_state)[:, 2])
    for _ in range(20):
        s = step(s, jnp.zeros((16, 8)))
    sink = z0 - np.asarray(position(s.pipeline_state)[:, 2])
    g = 9.81
    net_weight = np.asarray(dyn.mass) * g - np.asarray(dyn.hydro.fluid_density * g * dyn.hydro.volume)
    assert np.corrcoef(net_weight, sink)[0, 1] > 0.9


def test_training_wrapper_gives_each_slot_and_each_episode_its_own_physics():
    """Randomization is per episode (the plant draws it at every reset): in the training wrapper each
    slot starts with its own parameters and gets new ones when its episode ends. Brax's per-slot
    randomization_fn is refused with a pointer to the config."""
    rand = E.make("BlueROV2Heavy-StationKeeping", randomization={"enabled": True}, episode_length=3)
    env = E.wrap_for_training(rand, episode_length=3)
    s = jax.jit(env.reset)(jax.random.split(jax.random.PRNGKey(1), 4))
    masses = np.asarray(s.info["params"].mass)
    assert len(set(np.round(masses, 5))) == 4
    step = jax.jit(env.step)
    for _ in range(3):  # the third step truncates every episode: all four slots start anew
        s = step(s, jnp.zeros((4, 8)))
    assert np.all(np.isfinite(np.asarray(s.obs)))
    assert not np.any(np.isclose(np.asarray(s.info["params"].mass), masses))
    with pytest.raises(ValueError, match="randomization=\\{'enabled': True\\}"):
        E.wrap_for_training(rand, episode_length=3, randomization_fn=lambda sys: (sys, None))


def test_passive_vehicle_drifts_with_the_current():
    env = E.make("BlueROV2Heavy-StationKeeping", current={"mode": "constant", "speed": (0.2, 0.3), "max_elevation_deg": 0.0},
                 reset={"velocity": 0.0, "angular_velocity": 0.0, "tilt": 0.0})
    keys = jax.random.split(jax.random.PRNGKey(4), 4)
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    s = reset(keys)
    current = np.asarray(s.pipeline_state.current.value)
    assert np.all(np.linalg.norm(current, axis=1) >= 0.2)
    position = jax.vmap(lambda ps: env.plant.vehicle_state(ps).position)
    p0 = np.asarray(position(s.pipeline_state))
    for _ in range(200):  # 10 s
        s = step(s, jnp.zeros((4, 8)))
    v_world = np.asarray(s.pipeline_state.physics.data.qvel[:, :2])
    np.testing.assert_allclose(v_world, current[:, :2], atol=0.03)
    drift = np.asarray(position(s.pipeline_state))[:, :2] - p0[:, :2]
    cos = np.sum(drift * current[:, :2], 1) / np.linalg.norm(drift, axis=1) / np.linalg.norm(current[:, :2], axis=1)
    assert np.all(cos > 0.99)


def test_ou_current_has_configured_mean_and_variance():
    cfg = CurrentConfig(mode="ou", speed=(0.2, 0.2), ou_rate=0.5, ou_sigma=0.05)
    state = jax.vmap(lambda k: sample_current(k, cfg))(jax.random.split(jax.random.PRNGKey(0), 2000))

    def run(state, key):
        def body(s, k):
            s = step_current(s, k, 0.05, cfg)
            return s, s.value

        return jax.lax.scan(body, state, jax.random.split(key, 400))[1]

    values = jax.jit(jax.vmap(run))(state, jax.random.split(jax.random.PRNGKey(1), 2000))  # (2000, 400, 3)
    dev = np.asarray(values[:, -1] - state.mean)  # after 20 s = 10 / rate: stationary
    assert np.abs(dev.mean(0)).max() < 0.005
    np.testing.assert_allclose(dev.std(0), 0.05, rtol=0.08)
    # and it reverts: the lag-20 (1 s) autocorrelation is exp(-rate * 1 s)
    a, b = np.asarray(values[:, 200] - state.mean), np.asarray(values[:, 220] - state.mean)
    assert np.mean(a * b) / np.mean(a * a) == pytest.approx(math.exp(-0.5), abs=0.05)


def test_unknown_names_and_keys_list_the_choices():
    with pytest.raises(ValueError, match=r"unknown env 'BlueROV2Heavy-Hover'; registered envs: \[.*'BlueROV2Heavy-StationKeeping'"):
        E.make("BlueROV2Heavy-Hover")
    with pytest.raises(ValueError, match=r"unknown config key 'episode_lenght'; valid keys: \[.*'episode_length'"):
        E.make("BlueROV2Heavy-StationKeeping", episode_lenght=10)
    with pytest.raises(ValueError, match=r"unknown config key 'reward.efort'; valid keys of reward: \[.*'effort'"):
        E.make("BlueROV2Heavy-StationKeeping", reward={"efort": 1.0})
    with pytest.raises(ValueError, match=r"current.mode' must be one of \['off', 'constant', 'ou'\]"):
        E.make("BlueROV2Heavy-StationKeeping", current={"mode": "strong"})
    with pytest.raises(ValueError, match=r"'control_dt' must be a number"):
        E.make("BlueROV2Heavy-StationKeeping", control_dt="fast")


def test_wrong_action_shape_is_an_error(sk):
    s = sk.reset(jax.random.PRNGKey(0))
    with pytest.raises(ValueError, match=r"action must have shape \(8,\).*got \(6,\)"):
        sk.step(s, jnp.zeros(6))


def test_default_configs_are_immutable_values():
    c = E.get_default_config("BlueROV2Heavy-CircleTracking")
    with pytest.raises(Exception):
        c.episode_length = 5
    assert E.get_default_config("BlueROV2Heavy-CircleTracking") == c
    env = E.make("BlueROV2Heavy-CircleTracking", episode_length=50)
    assert env.config.episode_length == 50 and E.get_default_config("BlueROV2Heavy-CircleTracking").episode_length == 400


def test_brax_registry_builds_our_envs():
    from brax import envs as brax_envs

    env = brax_envs.get_environment("BlueROV2-StationKeeping", episode_length=20)
    assert env.action_size == 6 and env.config.episode_length == 20


@pytest.mark.parametrize("name", ["BlueROV2Heavy-StationKeeping", "BlueROV2Heavy-CircleTracking", "Remus100-CircleFollowing",
                                  "Remus100-Autopilot"])
def test_integral_observation_is_the_leaky_clipped_error_integral(name):
    """info['integral'] follows I ← exp(−dt/T) I + dt clip(e, ±c) of the true error, and the last four
    observation components are its body-frame position part and its heading part. The error is the
    position error to the target (station, reference point, the path's closest point) and the heading
    error; the autopilot's is the depth error alone (as world z) and the heading error to its set-points."""
    from marinejax.envs.base import heading_error
    from marinejax.frames import quat_to_mat

    env = E.make(name, integral_time_constant=2.0)
    c = env.config
    step = jax.jit(env.step)
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    expected = np.zeros(4)
    leak = math.exp(-c.control_dt / c.integral_time_constant)
    action = jnp.full(env.action_size, 0.2)
    for _ in range(40):  # 2 s: long enough for the clip (start errors up to 2 m) and the leak to matter
        state = step(state, action)
        vs = env.plant.vehicle_state(state.pipeline_state)
        if name.endswith("Autopilot"):
            depth, heading, _ = env.set_point(state.info)
            error = np.array([0.0, 0.0, float(depth - vs.position[2]), float(heading_error(vs.quaternion, heading))])
        else:
            error = np.concatenate([np.asarray(env.target_position(state.info) - vs.position),
                                    [float(heading_error(vs.quaternion, state.info["task"].yaw))]])
        expected = leak * expected + c.control_dt * np.clip(error, -c.integral_error_clip, c.integral_error_clip)
    np.testing.assert_allclose(np.asarray(state.info["integral"]), expected, rtol=1e-4, atol=1e-6)
    rot = np.asarray(quat_to_mat(vs.quaternion))
    np.testing.assert_allclose(np.asarray(state.obs[-4:-1]), rot.T @ expected[:3], rtol=1e-4, atol=1e-6)
    assert float(state.obs[-1]) == pytest.approx(expected[3], rel=1e-4, abs=1e-6)
    assert np.abs(expected).max() > 0.01  # a non-trivial integral was checked
    off = E.make(name, integral_time_constant=0.0)
    assert off.observation_size == env.observation_size - 4


def test_integral_settings_are_validated():
    with pytest.raises(ValueError, match="integral_time_constant"):
        E.make("BlueROV2Heavy-StationKeeping", integral_time_constant=-1.0)
    with pytest.raises(ValueError, match="integral_error_clip"):
        E.make("BlueROV2Heavy-StationKeeping", integral_error_clip=0.0)


def test_disturbance_force_pushes_the_vehicle_along_its_world_direction():
    """A constant world-frame force drawn per episode: the vehicle drifts along it (against the same
    episode without it), and the variant envs switch on randomization, OU current and disturbance."""
    calm = E.make("BlueROV2Heavy-StationKeeping", disturbance={"force": (4.0, 4.0), "torque": (0.0, 0.0)})
    pushed = E.make("BlueROV2Heavy-StationKeeping", disturbance={"enabled": True, "force": (4.0, 4.0), "torque": (0.0, 0.0)})
    key = jax.random.PRNGKey(7)
    finals = []
    for env in (calm, pushed):
        state = jax.jit(env.reset)(key)
        step = jax.jit(env.step)
        for _ in range(60):  # 3 s
            state = step(state, jnp.zeros(env.action_size))
        finals.append(np.asarray(env.plant.vehicle_state(state.pipeline_state).position))
    force = np.asarray(state.info["params"].disturbance[:3])
    assert np.linalg.norm(force) == pytest.approx(4.0, rel=1e-5)
    drift = finals[1] - finals[0]
    assert np.linalg.norm(drift) > 0.05
    assert drift @ force / (np.linalg.norm(drift) * np.linalg.norm(force)) > 0.95
    c = E.get_default_config("BlueROV2Heavy-StationKeepingDisturbed")
    assert c.randomization.enabled and c.current.mode == "ou" and c.disturbance.enabled
    assert not E.get_default_config("BlueROV2Heavy-StationKeeping").disturbance.enabled
    with pytest.raises(ValueError, match="disturbance.force"):
        E.make("BlueROV2Heavy-StationKeeping", disturbance={"force": (-1.0, 2.0)})


@pytest.mark.parametrize("name, max_distance", [("BlueROV2Heavy-StationKeeping", 5.0), ("BlueROV2Heavy-CircleTracking", 50.0)])
def test_window_error_sums_to_the_evaluation_statistic(name, max_distance):
    """Summed over an episode (as Brax's evaluation does), metrics['window_error'] is the mean position
    error over the task's window, the statistic `marinejax eval` reports; early termination counts
    as at least max_distance. (Tracking gets a wide work area so that an idle vehicle stays in it.)"""
    env = E.make(name, max_distance=max_distance)
    n = env.config.episode_length
    keys = jax.random.split(jax.random.PRNGKey(5), 2)
    actions = jnp.zeros((2, n, env.action_size)).at[1].set(1.0)  # row 1: full throttle leaves the work area
    _, (_, _, done, metrics) = episode_fn(env)(keys, actions)
    time = env.config.control_dt * np.arange(1, n + 1)
    window = np.asarray(env.error_window(time))
    assert 0 < window.sum() < n
    err = np.asarray(metrics["position_error"][0])
    assert not np.asarray(done[0]).any()
    assert float(np.sum(metrics["window_error"][0])) == pytest.approx(err[window].mean(), rel=1e-5)
    if max_distance > 10:
        return
    first_done = int(np.argmax(np.asarray(done[1]) > 0))
    assert np.asarray(done[1]).any()
    assert float(np.sum(metrics["window_error"][1][: first_done + 1])) >= env.config.max_distance


# one env per registered task (its first vehicle of the task's kind)
def _task_and_kind(name: str) -> tuple[str, str]:
    spec = E.env_spec(name)
    return spec.task, vehicle_kind(spec.vehicle)


# one env per task and vehicle kind (a task name may have a class per kind: Docking)
_ONE_PER_TASK = sorted({min(n for n in E.list_envs() if _task_and_kind(n) == key)
                        for key in {_task_and_kind(n) for n in E.list_envs()} if not key[0].endswith("Disturbed")})


@pytest.mark.parametrize("name", _ONE_PER_TASK)
def test_the_observation_layout_names_every_component_with_its_unit_and_frame(name):
    env = E.make(name)
    layout = env.observation_layout()
    covered = np.zeros(env.observation_size, bool)
    for field in layout:
        covered[field["start"] : field["stop"]] = True
        assert field["unit"] and field["frame"] and field["meaning"]
    assert covered.all() and layout[-1]["stop"] == env.observation_size
