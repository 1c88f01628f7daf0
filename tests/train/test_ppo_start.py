"""How a PPO run starts (`ppo.initial_params`): Brax's own start; `normalizer_warmup`, the observation
normalizer from the statistics of a short random-action rollout instead of Brax's mean 0 and std 1,
with Brax's own initial networks; `init_from`, another run's or a shipped policy's checkpoint."""

import re

import jax
import numpy as np
import pytest

import marinejax as mj
from marinejax.errors import UserError
from marinejax.train import ppo

ENV = "BlueROV2Heavy-StationKeeping"
SMALL = dict(num_envs=8, batch_size=8, num_minibatches=2, policy_hidden=(16,), value_hidden=(16,))


@pytest.fixture(scope="module")
def env():
    return mj.make(ENV)


def test_the_normalizer_holds_the_mean_and_std_of_a_random_action_rollout(env):
    config = ppo.Config(**SMALL, normalizer_warmup=6)
    obs = np.asarray(ppo.warmup_observations(env, config, seed=3))
    assert obs.shape == (6, 8, env.observation_size) and np.isfinite(obs).all()
    assert np.abs(np.diff(obs, axis=0)).max(axis=(0, 1)).max() > 0.01  # the envs moved
    assert np.abs(obs[:, 0] - obs[:, 1]).max() > 0.01  # and differ from each other
    normalizer = ppo.warmup_normalizer(env, config, seed=3)  # its own rollout: the same seed, the same observations
    assert int(normalizer.count.lo) == 48 and int(normalizer.count.hi) == 0
    flat = obs.reshape(-1, env.observation_size).astype(np.float64)
    np.testing.assert_allclose(np.asarray(normalizer.mean), flat.mean(axis=0), rtol=1e-4, atol=1e-6)
    # Brax floors the std at 1e-6 (a constant observation component)
    np.testing.assert_allclose(np.asarray(normalizer.std), np.maximum(flat.std(axis=0), 1e-6), rtol=1e-3, atol=1e-6)


def test_run_hands_brax_its_own_initial_networks_with_the_warm_normalizer_and_not_on_resume(env, monkeypatch, tmp_path):
    from brax.training.agents.ppo import train as ppo_train

    from marinejax.train.runner import wrap_for_training

    config = ppo.Config(**SMALL, normalizer_warmup=4)
    # Brax's own initialisation for seed 5: train for 0 steps returns its initial params
    _, (_, brax_policy, brax_value), _ = ppo_train.train(
        environment=env, num_timesteps=0, episode_length=env.config.episode_length, num_envs=8, batch_size=8,
        num_minibatches=2, seed=5, network_factory=ppo.env_network_factory(config, env), wrap_env_fn=wrap_for_training)
    calls = []
    monkeypatch.setattr(ppo_train, "train", lambda **kwargs: calls.append(kwargs))
    common = dict(num_timesteps=1000, seed=5, wrap_env_fn=wrap_for_training, progress_fn=None, save_fn=None, devices=1,
                  checkpoint_dir=tmp_path)
    ppo.run(env, config, restore=None, **common)
    normalizer, policy, value = calls[-1]["restore_params"]
    assert int(normalizer.count.lo) == 4 * 8
    np.testing.assert_array_equal(np.asarray(normalizer.mean), np.asarray(ppo.warmup_normalizer(env, config, 5).mean))
    for ours, brax in ((policy, brax_policy), (value, brax_value)):
        for a, b in zip(jax.tree.leaves(ours), jax.tree.leaves(brax), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    ppo.run(env, config, restore=tmp_path / "checkpoint", **common)  # a resumed run keeps its checkpoint's normalizer
    assert calls[-1]["restore_params"] is None and calls[-1]["restore_checkpoint_path"] == str(tmp_path / "checkpoint")
    ppo.run(env, ppo.Config(**SMALL), restore=None, **common)  # 0: Brax's own start
    assert calls[-1]["restore_params"] is None


def test_init_from_hands_brax_the_checkpoint_s_params_and_a_resume_its_own(monkeypatch, tmp_path):
    from brax.training.agents.ppo import train as ppo_train

    from marinejax.train.checkpoints import load_params
    from marinejax.train.hyperparams import tuned_config

    config = tuned_config("Remus100-HelixFollowing").ppo  # the recipe: the shipped circle policy, fine-tuned
    assert config.init_from == "Remus100-CircleFollowing"
    env = mj.make("Remus100-HelixFollowing")
    calls = []
    monkeypatch.setattr(ppo_train, "train", lambda **kwargs: calls.append(kwargs))
    common = dict(num_timesteps=1000, seed=0, wrap_env_fn=None, progress_fn=None, save_fn=None, devices=1, checkpoint_dir=tmp_path)
    ppo.run(env, config, restore=None, **common)
    _, _, shipped, ckpt = load_params("Remus100-CircleFollowing")
    assert ckpt.name == "000007598080"  # its best
    for ours, theirs in zip(jax.tree.leaves(calls[-1]["restore_params"]), jax.tree.leaves(shipped), strict=True):
        np.testing.assert_array_equal(np.asarray(ours), np.asarray(theirs))
    ppo.run(env, config, restore=tmp_path / "checkpoint", **common)  # resuming continues the run's own checkpoint
    assert calls[-1]["restore_params"] is None and calls[-1]["restore_checkpoint_path"] == str(tmp_path / "checkpoint")


def test_every_recipe_that_starts_from_a_policy_fits_it(monkeypatch):
    # the REMUS's curved paths and waypoints, every disturbed path and its docking start from its
    # circle policy, its disturbed autopilot from its autopilot policy; the four-fin variant (another
    # action size) from the same REMUS policies, and its autopilot and circle from the REMUS's; each
    # ROV's docking starts from its station keeping
    import dataclasses

    def zero_observations(env, config, seed):
        # what is checked is the fit (fields, sizes, actions): a docking's warm-up for its new field
        # would compile a rollout per env (about 20 s each); test_init_from_a_policy_without_a_field_...
        # checks its statistics
        obs = jax.eval_shape(env.reset, jax.random.PRNGKey(seed)).obs
        return jax.tree_util.tree_map(lambda s: np.zeros((1, config.num_envs, *s.shape), s.dtype), obs)

    monkeypatch.setattr(ppo, "warmup_observations", zero_observations)

    from marinejax.train.hyperparams import tuned_config

    starting = {name: tuned_config(name).ppo for name in mj.list_envs() if tuned_config(name).ppo.init_from}
    paths_ = {f"Remus100-{p}Following" for p in ("Helix", "Lemniscate", "Waypoint")} | {"Remus100-Docking"}
    rovs = {f"{v}-Docking{d}" for v in ("BlueROV2", "BlueROV2Heavy") for d in ("", "Disturbed")}
    remus = paths_ | {f"{n}Disturbed" for n in paths_ | {"Remus100-CircleFollowing", "Remus100-Autopilot"}}
    four_fin = {name.replace("Remus100-", "Remus100FourFin-") for name in remus | {"Remus100-CircleFollowing", "Remus100-Autopilot"}}
    assert set(starting) == remus | four_fin | rovs
    assert starting["Remus100-AutopilotDisturbed"].init_from == "Remus100-Autopilot"
    assert {starting[name].init_from for name in four_fin} == {"Remus100-Autopilot", "Remus100-CircleFollowing"}
    assert starting["BlueROV2-DockingDisturbed"].init_from == "BlueROV2-StationKeepingDisturbed"
    for name, config in starting.items():
        config = dataclasses.replace(config, num_envs=8)
        params = ppo.initial_params(mj.make(name, **tuned_config(name).env_overrides), config, seed=0)
        assert len(params) == 3, name


@pytest.mark.parametrize("env_name, settings, message", [
    ("Remus100-HelixFollowing", {"mirror_symmetric": False}, "has mirror_symmetric True, this run False"),
    ("Remus100-HelixFollowing", {"mirror_symmetric": True, "policy_hidden": (32, 32)}, "has policy_hidden (64, 64), this run (32, 32)"),
    (ENV, {"mirror_symmetric": True}, "has action size 3, this run 8"),
    ("Remus100-Autopilot", {"mirror_symmetric": True},
     "has observation size 39, this run 27: this env lacks its fields ['position_error', 'path_ahead', 'tangent']"),
    ("Remus100-HelixFollowing", {"mirror_symmetric": True, "normalizer_warmup": 5},
     "ppo 'normalizer_warmup' 5 has nothing to warm: 'init_from' 'Remus100-CircleFollowing'"),
    ("Remus100-Docking", {"mirror_symmetric": True}, "lacks this env's observation fields ['dock']: set --ppo normalizer_warmup=N"),
])
def test_init_from_a_checkpoint_that_does_not_fit_names_the_difference(env_name, settings, message):
    config = ppo.Config(init_from="Remus100-CircleFollowing", **settings)
    with pytest.raises(UserError, match=re.escape(message)):
        ppo.initial_params(mj.make(env_name), config, seed=0)


def test_init_from_something_that_is_not_a_run_lists_the_shipped_policies(tmp_path):
    from marinejax.train.checkpoints import CheckpointError

    with pytest.raises(CheckpointError, match=r"no such run directory or checkpoint: .*nowhere \(shipped policies: .*Remus100-CircleFollowing"):
        ppo.initial_params(mj.make(ENV), ppo.Config(init_from=str(tmp_path / "nowhere")), seed=0)


def _networks(config, env):
    """The PPO networks of `config` for `env`, normalizing their observations as Brax's PPO does."""
    from brax.training.acme import running_statistics

    return ppo.env_network_factory(config, env)(env.observation_size, env.action_size,
                                                preprocess_observations_fn=running_statistics.normalize)


def test_init_from_a_policy_without_a_field_starts_from_the_source_policy_and_value():
    # the shipped circle policy on the torpedo's docking, whose observation adds the `dock` field
    # (the latch point from the nose) amid the circle's: the widened networks compute the source's
    # functions of the fields they share, whatever the new field holds, and the new field's
    # normalizer holds the warm-up rollout's statistics
    from marinejax.train.checkpoints import load_params

    env = mj.make("Remus100-Docking")
    config = ppo.Config(init_from="Remus100-CircleFollowing", mirror_symmetric=True, normalizer_warmup=3, num_envs=8, batch_size=8,
                        num_minibatches=2)
    normalizer, policy, value = ppo.initial_params(env, config, seed=2)
    _, source_env, (s_normalizer, s_policy, s_value), _ = load_params("Remus100-CircleFollowing")
    dock = env.observation_fields()["dock"]
    assert (dock.start, dock.stop) == (35, 38) and source_env.observation_size == env.observation_size - 3
    keep = np.r_[0:dock.start, dock.stop:env.observation_size]
    warm = ppo.warmup_normalizer(env, config, seed=2)
    np.testing.assert_array_equal(np.asarray(normalizer.mean)[keep], np.asarray(s_normalizer.mean))
    np.testing.assert_array_equal(np.asarray(normalizer.std)[keep], np.asarray(s_normalizer.std))
    np.testing.assert_allclose(np.asarray(normalizer.mean)[dock], np.asarray(warm.mean)[dock], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(normalizer.std)[dock], np.asarray(warm.std)[dock], rtol=1e-6)
    assert np.asarray(warm.std)[dock][0] > 2.0  # metres to the latch along the axis: the rollout's spread, not Brax's 1
    assert normalizer.count == s_normalizer.count

    obs = np.array(ppo.warmup_observations(env, config, seed=7)).reshape(-1, env.observation_size)
    obs[::2, dock] += np.array([5.0, -3.0, 2.0])  # any value of the new field: no effect at the start
    networks, s_networks = _networks(config, env), _networks(config, source_env)
    ours = networks.policy_network.apply(normalizer, policy, obs), networks.value_network.apply(normalizer, value, obs)
    theirs = (s_networks.policy_network.apply(s_normalizer, s_policy, obs[:, keep]),
              s_networks.value_network.apply(s_normalizer, s_value, obs[:, keep]))
    for a, b in zip(ours, theirs, strict=True):
        assert np.abs(np.asarray(b)).max() > 0.1
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-5)


def test_the_four_fin_variant_starts_from_the_remus_policy_flying_its_fins_alike():
    # the shipped REMUS circle policy (rudder, stern planes, propeller) on the four-fin variant's
    # docking (four fins, and the new `dock` field): each fin takes the command of the pair it
    # belongs to, signed as `steering_mix` says, so the policy's actions and value are the source's
    # wherever the fins' states follow their pair's
    from marinejax.envs.symmetry import FIELD_SIGNS
    from marinejax.train.checkpoints import load_params

    env = mj.make("Remus100FourFin-Docking")
    config = ppo.Config(init_from="Remus100-CircleFollowing", mirror_symmetric=True, normalizer_warmup=3, num_envs=8, batch_size=8,
                        num_minibatches=2)
    normalizer, policy, value = ppo.initial_params(env, config, seed=2)
    _, source_env, (s_normalizer, s_policy, s_value), _ = load_params("Remus100-CircleFollowing")
    actions = ppo.action_map(source_env, env, "the circle policy")
    # rudder to the top (+) and bottom (−) fins, stern planes to the port (−) and starboard (+) ones
    np.testing.assert_array_equal(actions.take, [0, 0, 1, 1, 2])
    np.testing.assert_array_equal(actions.sign, [1, -1, -1, 1, 1])

    obs = np.array(ppo.warmup_observations(env, config, seed=7)).reshape(-1, env.observation_size)
    fields, s_fields = env.observation_fields(), source_env.observation_fields()
    s_obs = np.zeros((len(obs), source_env.observation_size), np.float32)
    first = [list(actions.take).index(i) for i in range(source_env.action_size)]  # each command's first actuator
    for name, s in s_fields.items():
        if FIELD_SIGNS[name] == "action":  # the fins follow their pair: the first fin's state, signed
            s_obs[:, s] = obs[:, fields[name]][:, first] * actions.sign[first]
            obs[:, fields[name]] = s_obs[:, s][:, actions.take] * actions.sign
        else:
            s_obs[:, s] = obs[:, fields[name]]
    assert np.abs(obs[:, fields["actuators"]]).max() > 0.1  # the fins are deflected
    networks, s_networks = _networks(config, env), _networks(config, source_env)
    ours = np.asarray(networks.policy_network.apply(normalizer, policy, obs))
    theirs = np.asarray(s_networks.policy_network.apply(s_normalizer, s_policy, s_obs))
    loc, scale = np.split(theirs, 2, axis=-1)
    assert np.abs(loc).max() > 0.1
    np.testing.assert_allclose(ours, np.concatenate([loc[:, actions.take] * actions.sign, scale[:, actions.take]], -1), rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(np.asarray(networks.value_network.apply(normalizer, value, obs)),
                               np.asarray(s_networks.value_network.apply(s_normalizer, s_value, s_obs)), rtol=1e-5, atol=1e-4)


def test_a_policy_whose_actions_another_vehicle_can_only_mix_is_refused():
    four_fin, remus, rov = mj.make("Remus100FourFin-Autopilot"), mj.make("Remus100-Autopilot"), mj.make(ENV)
    with pytest.raises(UserError, match=re.escape("x has action size 5, this run 3, and its actuators map to this vehicle's only by mixing")):
        ppo.action_map(four_fin, remus, "x")
    with pytest.raises(UserError, match=re.escape("x has action size 3, this run 8 (--ppo init_from= trains from scratch)")):
        ppo.action_map(remus, rov, "x")


@pytest.mark.parametrize("settings, message", [
    ({"normalizer_warmup": -1}, "ppo 'normalizer_warmup' must be >= 0 (steps), got -1"),
    ({"normalizer_warmup": 5, "normalize_observations": False}, "ppo 'normalizer_warmup' needs normalize_observations = true"),
])
def test_bad_values_are_user_errors(settings, message):
    with pytest.raises(UserError, match=re.escape(message)):
        ppo.Config(**settings)
