"""Mirror symmetry (`envs.symmetry`, `ppo.Config.mirror_symmetric`): the reflection y → −y maps a
situation of the torpedo to its mirror image and the policy's action to the mirrored action; the
exported policy (NumPy, ONNX) is the same function as the JAX one."""

import dataclasses
import json
import shutil
from importlib import resources

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.envs.symmetry import env_mirror
from marinejax.errors import UserError
from marinejax.export import export_policy, load_numpy_policy
from marinejax.frames import quat_from_euler
from marinejax.physics import VehicleState
from marinejax.train.checkpoints import load_policy


def test_action_mirrors_follow_the_actuator_sites():
    # REMUS: one rudder (its lift along body y flips), the stern planes and the propeller stay
    perm, sign = mj.load_vehicle("remus100").action_mirror()
    assert perm.tolist() == [0, 1, 2] and sign.tolist() == [-1, 1, 1]
    # four fins: the rudders flip, the port and starboard stern planes swap (their lift axes are opposite)
    perm, sign = mj.load_vehicle("remus100_four_fin").action_mirror()
    assert perm.tolist() == [0, 1, 3, 2, 4] and sign.tolist() == [-1, -1, -1, -1, 1]
    # the Heavy's thrusters swap in left/right pairs
    perm, sign = mj.load_vehicle("bluerov2_heavy").action_mirror()
    assert perm.tolist() == [1, 0, 3, 2, 5, 4, 7, 6] and sign.tolist() == [1] * 8


def _reflect_state(vs: VehicleState) -> VehicleState:
    """The mirror image y → −y of a vehicle state: positions and velocities flip y, angular velocity x
    and z, the attitude (roll, pitch, yaw) → (−roll, pitch, −yaw), fin angles by the action mirror."""
    w, x, y, z = vs.quaternion
    return vs.replace(position=vs.position * jnp.array([1.0, -1.0, 1.0]), quaternion=jnp.array([w, -x, y, -z]),
                      velocity=vs.velocity * jnp.array([1.0, -1.0, 1.0]),
                      angular_velocity=vs.angular_velocity * jnp.array([-1.0, 1.0, -1.0]),
                      actuators=vs.actuators * jnp.array([-1.0, 1.0, 1.0]))


def test_the_reflected_circle_is_observed_as_the_mirrored_observation_and_turns_the_mirrored_way():
    env = mj.make("Remus100-CircleFollowing")
    mirror = env_mirror(env)
    state = env.reset(jax.random.PRNGKey(0))
    task = state.info["task"]
    # this episode's circle and its mirror image: centre y flipped, direction reversed, phase negated
    path = task.path
    image_path = path.replace(center=path.center * jnp.array([1.0, -1.0, 1.0]), direction=-path.direction, phase=-path.phase)
    vs = VehicleState(position=jnp.array([0.3, -0.4, path.center[2] + 0.2]), quaternion=quat_from_euler(0.05, -0.1, 0.3),
                      velocity=jnp.array([1.4, 0.1, -0.05]), angular_velocity=jnp.array([0.02, -0.03, 0.05]),
                      actuators=jnp.array([0.1, -0.05, 900.0]))
    action = jnp.array([0.3, -0.2, 0.6])
    info = {**state.info, "task": env.advance_task(task, vs, state.info)}
    image_info = {**state.info, "task": env.advance_task(task.replace(path=image_path), _reflect_state(vs), state.info)}
    info["integral"] = jnp.array([0.1, 0.2, -0.3, 0.05])
    image_info["integral"] = jnp.array([0.1, -0.2, -0.3, -0.05])
    obs = env._observation(vs, info, action, None)
    image_obs = env._observation(_reflect_state(vs), image_info, mirror.action(action), None)
    np.testing.assert_allclose(image_obs, mirror.observation(obs), atol=2e-5)
    assert np.abs(obs - mirror.observation(obs)).max() > 0.1  # a situation unlike its mirror image
    # mirrored commands from the mirrored state: the mirrored path (the propeller's torque, which a
    # mirrored propeller would reverse, rolls both the same way: a small difference)
    start = VehicleState(position=jnp.zeros(3), quaternion=quat_from_euler(0.0, 0.0, 0.0), velocity=jnp.array([1.5, 0.0, 0.0]),
                         angular_velocity=jnp.zeros(3), actuators=jnp.array([0.0, 0.0, 900.0]))
    commands = np.tile([0.5, -0.2, 0.6], (100, 1)).astype(np.float32)
    traj = jax.tree.map(np.asarray, mj.rollout(env.vehicle, commands, start, control_dt=0.1, substeps=2))
    image = jax.tree.map(np.asarray, mj.rollout(env.vehicle, np.asarray(mirror.action(commands)), _reflect_state(start),
                                                control_dt=0.1, substeps=2))
    assert abs(traj.position[-1, 1]) > 4.0  # 10 s of a half rudder: a turn
    np.testing.assert_allclose(image.position[-1], traj.position[-1] * [1, -1, 1], atol=0.05)
    np.testing.assert_allclose(image.angular_velocity[-1, 2], -traj.angular_velocity[-1, 2], rtol=0.02)


def test_envs_with_a_field_without_mirror_image_are_refused():
    env = mj.make("BlueROV2Heavy-StationKeeping")
    env_mirror(env)  # every field has an image
    with pytest.raises(UserError, match="no mirror image"):
        env_mirror(mj.make("BlueROV2-ObstacleAvoidance"))  # the sonar fan


@pytest.fixture(scope="module")
def symmetric_policy(tmp_path_factory):
    """The shipped waypoint policy's weights run as a mirror-symmetric policy (its config.json says so)."""
    run = tmp_path_factory.mktemp("symmetric") / "run"
    shutil.copytree(resources.files("marinejax") / "policies" / "Remus100-WaypointFollowing", run)
    config = json.loads((run / "config.json").read_text())
    config["ppo"]["mirror_symmetric"] = True
    (run / "config.json").write_text(json.dumps(config))
    _, env, policy, _ = load_policy(run)
    return run, env, policy


def test_a_symmetric_policy_acts_the_mirror_image_and_exports_as_itself(tmp_path, symmetric_policy):
    run, env, policy = symmetric_policy
    mirror = env_mirror(env)
    keys = jax.random.split(jax.random.PRNGKey(1), 64)
    obs = np.asarray(jax.vmap(lambda k: env.reset(k).obs)(keys))
    obs = obs + np.random.default_rng(0).normal(0.0, 0.3, obs.shape).astype(np.float32)
    act = np.asarray(jax.jit(jax.vmap(policy))(obs))
    image = np.asarray(jax.jit(jax.vmap(policy))(mirror.observation(obs)))
    np.testing.assert_allclose(image, mirror.action(act), atol=1e-6)
    assert np.abs(act[:, 0]).max() > 0.05  # the rudder commands are not all zero (a trivial equivariance)
    numpy_policy = load_numpy_policy(export_policy(run, "npz", tmp_path / "p.npz"))
    np.testing.assert_allclose(numpy_policy(obs), act, atol=1e-5)
    assert "mirror-symmetric" in numpy_policy.metadata["network"]
    ort = pytest.importorskip("onnxruntime")
    session = ort.InferenceSession(str(export_policy(run, "onnx", tmp_path / "p.onnx")), providers=["CPUExecutionProvider"])
    (onnx_act,) = session.run(["action"], {"observation": obs.astype(np.float32)})
    np.testing.assert_allclose(onnx_act, act, atol=1e-5)
    # the same weights without the symmetry act otherwise
    plain = dataclasses.replace(numpy_policy, mirror=None)
    assert np.abs(plain(obs) - act).max() > 1e-3


def test_a_symmetric_network_needs_its_env():
    from marinejax.train.hyperparams import network_factory, tuned_config

    settings = dataclasses.replace(tuned_config("Remus100-CircleFollowing").ppo, mirror_symmetric=True)
    with pytest.raises(UserError, match="needs its env"):
        network_factory(settings, 39)
    env = mj.make("Remus100-CircleFollowing")
    networks = network_factory(settings, env=env)(env.observation_size, env.action_size)
    params = networks.policy_network.init(jax.random.PRNGKey(0))
    obs = jax.random.normal(jax.random.PRNGKey(1), (8, env.observation_size))
    from brax.training.acme import running_statistics

    out = networks.policy_network.apply(running_statistics.init_state(jnp.zeros(env.observation_size)), params, obs)
    image = networks.policy_network.apply(running_statistics.init_state(jnp.zeros(env.observation_size)), params,
                                          env_mirror(env).observation(obs))
    # the location half mirrors, the scale half is permuted (the REMUS's actions map to themselves)
    np.testing.assert_allclose(image[:, :3], out[:, :3] * np.array([-1, 1, 1]), atol=1e-6)
    np.testing.assert_allclose(image[:, 3:], out[:, 3:], atol=1e-6)


def test_training_a_symmetric_policy_on_an_env_without_mirror_image_is_a_user_error():
    from marinejax.train.hyperparams import build_env, tuned_config, with_overrides

    config = with_overrides(tuned_config("BlueROV2-ObstacleAvoidance"), ppo={"mirror_symmetric": True})
    with pytest.raises(UserError, match=r"\['sonar'\] have no mirror image"):
        build_env(config)
