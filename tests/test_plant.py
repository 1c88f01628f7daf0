"""The plant layer: explicit per-episode parameters, a pure step equal to the physics, privileged state."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.frames import quat_to_mat
from marinejax.physics import initial_state, rollout
from marinejax.plant import Plant, PlantConfig, RandomizationConfig, apply_params, nominal_params

STEPS = 40


@pytest.fixture(scope="module")
def plant():
    return Plant("bluerov2_heavy", PlantConfig())


@pytest.fixture(scope="module")
def run(plant):
    """jit: STEPS plant steps from a state at rest under constant throttles, with the given params."""

    def go(params, action):
        start = initial_state(plant.vehicle, position=(0.0, 0.0, -5.0))
        state = plant.init(jax.random.PRNGKey(0), params, start)

        def body(s, k):
            s, finite = plant.step(params, s, action, k)
            return s, (plant.vehicle_state(s).position, finite)

        _, out = jax.lax.scan(body, state, jax.random.split(jax.random.PRNGKey(1), STEPS))
        return out

    return jax.jit(go)


def test_nominal_params_are_the_loaded_vehicle(plant):
    p = plant.nominal_params()
    sys = plant.vehicle.sys
    assert float(p.mass) == pytest.approx(13.5)
    np.testing.assert_array_equal(np.asarray(p.disturbance), np.zeros(6))
    back = apply_params(sys, nominal_params(sys))
    for a, b in zip(jax.tree.leaves(back), jax.tree.leaves(sys)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # without randomization and disturbance, drawing gives the nominal parameters for any key
    drawn = plant.sample_params(jax.random.PRNGKey(5))
    for a, b in zip(jax.tree.leaves(drawn), jax.tree.leaves(p)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_plant_step_is_the_physics_rollout(plant, run):
    """The plant adds nothing to the physics: same positions as marinejax.rollout, to float rounding."""
    action = jnp.array([0.3, 0.3, -0.3, -0.3, 0.2, 0.2, 0.2, 0.2])
    positions, finite = run(plant.nominal_params(), action)
    traj = rollout(plant.vehicle, np.tile(np.asarray(action), (STEPS, 1)),
                   initial_state(plant.vehicle, position=(0.0, 0.0, -5.0)))
    assert bool(np.all(finite))
    np.testing.assert_allclose(np.asarray(positions), np.asarray(traj.position), atol=1e-5)


def test_explicit_params_change_the_motion(plant, run):
    """A vehicle 2 kg heavier (same volume) sinks faster: 19.6 N more net weight."""
    nominal = plant.nominal_params()
    heavy = nominal.replace(mass=nominal.mass + 2.0)
    assert float(heavy.net_buoyancy(plant.gravity)) == pytest.approx(float(nominal.net_buoyancy(plant.gravity)) - 2.0 * 9.81, rel=1e-4)
    z_nominal = np.asarray(run(nominal, jnp.zeros(8))[0])[-1, 2]
    z_heavy = np.asarray(run(heavy, jnp.zeros(8))[0])[-1, 2]
    assert z_heavy < z_nominal - 0.3


def test_randomized_params_cover_the_configured_ranges():
    cfg = RandomizationConfig(enabled=True, mass_scale=(0.9, 1.1), net_buoyancy=(-1.5, 1.5))
    plant = Plant("bluerov2_heavy", PlantConfig(randomization=cfg))
    p = jax.vmap(plant.sample_params)(jax.random.split(jax.random.PRNGKey(0), 500))
    mass = np.asarray(p.mass)
    assert 13.5 * 0.9 - 1e-4 <= mass.min() < 13.5 * 0.92 and 13.5 * 1.08 < mass.max() <= 13.5 * 1.1 + 1e-4
    shift = np.asarray(p.net_buoyancy(plant.gravity)) - float(plant.nominal_params().net_buoyancy(plant.gravity))
    assert -1.5 - 1e-3 <= shift.min() < -1.3 and 1.3 < shift.max() <= 1.5 + 1e-3
    np.testing.assert_array_equal(np.asarray(p.disturbance), 0.0)  # disturbance has its own switch


def test_non_finite_step_keeps_the_last_state(plant):
    params = plant.nominal_params()
    state = plant.init(jax.random.PRNGKey(0), params, initial_state(plant.vehicle))
    bad = params.replace(mass=jnp.float32(np.nan))
    new, finite = jax.jit(plant.step)(bad, state, jnp.zeros(8), jax.random.PRNGKey(1))
    assert not bool(finite)
    np.testing.assert_array_equal(np.asarray(new.physics.data.qpos), np.asarray(state.physics.data.qpos))


def test_env_reset_with_params_runs_the_episode_with_them():
    env = mj.make("BlueROV2Heavy-StationKeeping")
    params = env.plant.nominal_params()
    params = params.replace(mass=params.mass * 1.05, disturbance=jnp.array([0.0, 0.0, 3.0, 0.0, 0.0, 0.0]))
    state = jax.jit(env.reset)(jax.random.PRNGKey(0), params)
    assert float(state.info["params"].mass) == pytest.approx(13.5 * 1.05)
    default = jax.jit(env.reset)(jax.random.PRNGKey(0))
    # same key, same target and start: only the parameters differ
    np.testing.assert_array_equal(np.asarray(state.obs), np.asarray(default.obs))


def test_privileged_observation_is_state_plus_what_no_sensor_gives():
    flat = mj.make("BlueROV2Heavy-StationKeepingDisturbed")
    priv = mj.make("BlueROV2Heavy-StationKeepingDisturbed", privileged_observation=True)
    n = flat.observation_size
    assert priv.observation_size == {"state": (n,), "privileged_state": (n + 45,)}  # 37 + 8 thruster gains
    key = jax.random.PRNGKey(3)
    s_flat, s_priv = jax.jit(flat.reset)(key), jax.jit(priv.reset)(key)
    np.testing.assert_array_equal(np.asarray(s_priv.obs["state"]), np.asarray(s_flat.obs))
    extra = np.asarray(s_priv.obs["privileged_state"][n:])
    rot = np.asarray(quat_to_mat(priv.plant.vehicle_state(s_priv.pipeline_state).quaternion))
    np.testing.assert_allclose(extra[:3], rot.T @ np.asarray(s_priv.pipeline_state.current.value), atol=1e-6)
    np.testing.assert_allclose(extra[6:9], np.asarray(s_priv.info["params"].disturbance[3:]), atol=1e-6)
    assert extra[9] == pytest.approx(float(s_priv.info["params"].mass))
    s_priv = jax.jit(priv.step)(s_priv, jnp.zeros(8))
    assert set(s_priv.obs) == {"state", "privileged_state"} and np.isfinite(np.asarray(s_priv.obs["privileged_state"])).all()
