"""Stable-Baselines3 and TorchRL on marinejax envs, by the paths their users take.

Optional: these run where the extra is installed (pip install -e ".[rl-test]"; CI does) and are
skipped otherwise. Compilation dominates, so every test uses the same env and config.
"""

import gymnasium
import numpy as np
import pytest

import marinejax  # noqa: F401  (registers the gymnasium ids)

NAME = "BlueROV2Heavy-CircleTracking"
ID = f"marinejax/{NAME}-v0"
LENGTH = 60
OBS, ACT = 38, 8  # BlueROV2 Heavy circle tracking

sb3 = pytest.importorskip("stable_baselines3", reason='needs the optional extra: pip install -e ".[rl-test]"')


def test_sb3_check_env_on_the_single_env():
    from stable_baselines3.common.env_checker import check_env

    check_env(gymnasium.make(ID, episode_length=LENGTH), warn=False)


def test_sb3_make_vec_env_with_four_envs_steps_and_renders():
    from stable_baselines3.common.env_util import make_vec_env

    venv = make_vec_env(ID, n_envs=4, seed=0, env_kwargs={"episode_length": LENGTH})
    obs = venv.reset()
    assert obs.shape == (4, OBS)
    obs, rewards, dones, infos = venv.step(np.zeros((4, ACT), np.float32))
    assert rewards.shape == (4,) and len(infos) == 4 and "position_error" in infos[0]
    assert venv.render_mode == "rgb_array"  # SB3 asks for rgb_array; the env accepts it


def test_shipped_sb3_vec_env_follows_sb3_conventions():
    from stable_baselines3.common.vec_env import VecMonitor

    from marinejax.envs.sb3 import MarineJaxSB3VecEnv

    venv = MarineJaxSB3VecEnv(NAME, num_envs=3, episode_length=LENGTH)
    venv.seed(5)
    first = venv.reset()
    venv.seed(5)
    np.testing.assert_array_equal(venv.reset(), first)  # seeded resets repeat
    assert venv.get_attr("episode_length") == [LENGTH] * 3 and venv.env_is_wrapped(VecMonitor) == [False] * 3
    monitored = VecMonitor(venv)
    monitored.reset()
    for t in range(LENGTH):
        obs, rewards, dones, infos = monitored.step(np.zeros((3, ACT), np.float32))
        assert rewards.dtype == np.float32 and dones.shape == (3,)
    assert dones.all() and all(info["TimeLimit.truncated"] for info in infos)
    assert all(info["terminal_observation"].shape == (OBS,) for info in infos)
    assert all(info["episode"]["l"] == LENGTH for info in infos)  # VecMonitor saw whole episodes
    assert not np.array_equal(obs, np.stack([info["terminal_observation"] for info in infos]))  # already reset


@pytest.mark.slow  # a learning check, and a chaotic one: it runs compiled as users' runs are (conftest.py)
def test_sb3_ppo_on_the_shipped_vec_env_raises_the_return():
    from stable_baselines3 import PPO
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import VecNormalize

    from marinejax.envs.sb3 import MarineJaxSB3VecEnv

    venv = MarineJaxSB3VecEnv(NAME, num_envs=8, episode_length=LENGTH)
    env = VecNormalize(venv, norm_obs=True, norm_reward=False)  # SB3's usual set-up for continuous control
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=128, n_epochs=5, learning_rate=1e-3, seed=0, device="cpu",
                policy_kwargs={"net_arch": [32, 32]})

    def mean_return():  # the same 8 evaluation episodes each time, observation statistics frozen
        venv.seed(123)
        env.training = False
        value = evaluate_policy(model, env, n_eval_episodes=8, deterministic=True)[0]
        env.training = True
        return value

    before = mean_return()
    model.learn(total_timesteps=49_152)
    after = mean_return()
    # Measured with this seed (jax 0.10.2): 121 before; 126, 127, 145, 163 after 12, 25, 37, 49 k steps.
    assert after > before + 15, (before, after)


torchrl = pytest.importorskip("torchrl", reason='needs the optional extra: pip install -e ".[rl-test]"')


def test_torchrl_gym_env_by_id_passes_check_env_specs():
    from torchrl.envs import GymEnv
    from torchrl.envs.utils import check_env_specs

    env = GymEnv(ID, episode_length=LENGTH)  # TorchRL tries frameskip= first and falls back on TypeError
    check_env_specs(env)
    rollout = env.rollout(5)
    assert rollout["observation"].shape == (5, OBS)


def test_torchrl_gym_wrapper_over_the_vector_env_and_a_collector():
    from torchrl.collectors import Collector
    from torchrl.envs import GymWrapper
    from torchrl.envs.utils import check_env_specs

    vec = gymnasium.make_vec(ID, num_envs=4, autoreset_mode="same_step", episode_length=LENGTH)
    env = GymWrapper(vec)
    check_env_specs(env)
    collector = Collector(env, policy=None, frames_per_batch=4 * 2 * LENGTH, total_frames=4 * 2 * LENGTH)
    batch = next(iter(collector))
    collector.shutdown()
    assert batch["next", "observation"].shape[-1] == OBS and batch.numel() == 4 * 2 * LENGTH
    assert int(batch["next", "done"].sum()) == 4 * 2  # every env finished two episodes of LENGTH steps
