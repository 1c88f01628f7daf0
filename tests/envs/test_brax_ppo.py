"""Brax's PPO trains our envs directly, with our full-reset wrapper, per-episode randomization and
an asymmetric critic on the privileged observation."""

import functools

import numpy as np
import pytest
from brax.training.agents.ppo import train as ppo

import marinejax.envs as E


@pytest.mark.slow
def test_ppo_train_runs_on_station_keeping_with_randomization_and_a_privileged_critic():
    """(The plain observation is what every CLI training test trains on.)"""
    env = E.make("BlueROV2Heavy-StationKeeping", episode_length=10, randomization={"enabled": True},
                 privileged_observation=True)
    keys = {"policy_obs_key": "state", "value_obs_key": "privileged_state"}
    progress = []
    _, params, metrics = ppo.train(
        environment=env,
        num_timesteps=640,
        episode_length=10,
        num_envs=8,
        batch_size=8,
        num_minibatches=2,
        unroll_length=5,
        num_updates_per_batch=1,
        num_evals=2,
        num_eval_envs=4,
        network_factory=functools.partial(
            __import__("brax.training.agents.ppo.networks", fromlist=["make_ppo_networks"]).make_ppo_networks,
            policy_hidden_layer_sizes=(16,),
            value_hidden_layer_sizes=(16,),
            **keys,
        ),
        wrap_env_fn=E.wrap_for_training,
        seed=0,
        progress_fn=lambda step, m: progress.append((step, m)),
    )
    assert len(progress) == 2
    last = progress[-1][1]
    assert np.isfinite(last["eval/episode_reward"])
    assert "eval/episode_position_error" in last and "eval/episode_reward/position" in last
    assert progress[-1][0] >= 640
