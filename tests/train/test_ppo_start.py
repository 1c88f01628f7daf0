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


def test_every_recipe_that_starts_from_a_policy_fits_it():
    # the REMUS's curved paths and waypoints, and every disturbed path, start from its circle policy,
    # its disturbed autopilot from its autopilot policy; the four-fin variant (another action size)
    # trains from scratch
    from marinejax.train.hyperparams import tuned_config

    starting = {name: tuned_config(name).ppo for name in mj.list_envs() if tuned_config(name).ppo.init_from}
    paths_ = {f"Remus100-{p}Following" for p in ("Helix", "Lemniscate", "Waypoint")}
    assert set(starting) == paths_ | {f"{n}Disturbed" for n in paths_ | {"Remus100-CircleFollowing", "Remus100-Autopilot"}}
    assert starting["Remus100-AutopilotDisturbed"].init_from == "Remus100-Autopilot"
    for name, config in starting.items():
        params = ppo.initial_params(mj.make(name, **tuned_config(name).env_overrides), config, seed=0)
        assert len(params) == 3, name


@pytest.mark.parametrize("env_name, settings, message", [
    ("Remus100-HelixFollowing", {"mirror_symmetric": False}, "has mirror_symmetric True, this run False"),
    ("Remus100-HelixFollowing", {"mirror_symmetric": True, "policy_hidden": (32, 32)}, "has policy_hidden (64, 64), this run (32, 32)"),
    (ENV, {}, "has observation size 39, this run 26"),
])
def test_init_from_a_checkpoint_that_does_not_fit_names_the_difference(env_name, settings, message):
    config = ppo.Config(init_from="Remus100-CircleFollowing", **settings)
    with pytest.raises(UserError, match=re.escape(message)):
        ppo.initial_params(mj.make(env_name), config, seed=0)


def test_init_from_something_that_is_not_a_run_lists_the_shipped_policies(tmp_path):
    from marinejax.train.checkpoints import CheckpointError

    with pytest.raises(CheckpointError, match=r"no such run directory or checkpoint: .*nowhere \(shipped policies: .*Remus100-CircleFollowing"):
        ppo.initial_params(mj.make(ENV), ppo.Config(init_from=str(tmp_path / "nowhere")), seed=0)


@pytest.mark.parametrize("settings, message", [
    ({"normalizer_warmup": -1}, "ppo 'normalizer_warmup' must be >= 0 (steps), got -1"),
    ({"normalizer_warmup": 5, "normalize_observations": False}, "ppo 'normalizer_warmup' needs normalize_observations = true"),
    ({"normalizer_warmup": 5, "init_from": "Remus100-CircleFollowing"}, "ppo 'init_from' and 'normalizer_warmup' exclude each other"),
])
def test_bad_values_are_user_errors(settings, message):
    with pytest.raises(UserError, match=re.escape(message)):
        ppo.Config(**settings)
