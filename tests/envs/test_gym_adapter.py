"""Gymnasium adapters: API conformance (check_env), registration, seeding, truncation, NEXT_STEP autoreset,
and equality of the batched vector env with single envs.

Compilation dominates: every adapter below uses the same env and config (episode_length=20), so they
share one set of jitted functions (the adapter caches them per env name and config).
"""

import warnings

import gymnasium
import jax
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import marinejax  # noqa: F401  (registers the gymnasium ids)
from marinejax.envs import list_envs
from marinejax.envs.gym_adapter import MarineJaxEnv, MarineJaxVectorEnv, gymnasium_id, register_gymnasium_envs

NAME = "BlueROV2Heavy-StationKeeping"
ID = f"marinejax/{NAME}-v0"
LENGTH = 20
N = 3
OBS, ACT = 26, 8  # BlueROV2 Heavy: 8 thrusters, observation 14 + 8 + 4 (integral)


@pytest.fixture(scope="module")
def single():
    return MarineJaxEnv(NAME, episode_length=LENGTH)


@pytest.fixture(scope="module")
def vec():
    return MarineJaxVectorEnv(NAME, num_envs=N, episode_length=LENGTH)


def random_actions(steps, seed=0):
    return np.random.default_rng(seed).uniform(-1, 1, (steps, N, ACT)).astype(np.float32)


def run_single(env, seed, actions):
    """Reset with `seed`, step `actions` until the episode ends: [(obs, reward, terminated, truncated)]."""
    obs, _ = env.reset(seed=seed)
    out = [(obs, 0.0, False, False)]
    for a in actions:
        obs, reward, terminated, truncated, _ = env.step(a)
        out.append((obs, reward, terminated, truncated))
        if terminated or truncated:
            break
    return out


def shift_target(state, index=None, offset=100.0):
    """`state` with the station target moved `offset` m away (of env `index` in a batch): the next step terminates."""
    task = state.info["task"]
    position = task.position + offset if index is None else task.position.at[index].add(offset)
    return state.replace(info={**state.info, "task": task.replace(position=position)})


def test_check_env_passes_with_only_the_unbounded_observation_warnings():
    env = gymnasium.make(ID, episode_length=LENGTH).unwrapped  # with a spec: check_env also rebuilds it
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    messages = [str(w.message) for w in caught]
    # The observations (errors, velocities) have no natural bounds: Box(-inf, inf) is intended.
    unexpected = [m for m in messages if "infinity" not in m]
    assert not unexpected, unexpected


def test_gymnasium_make_by_id_passes_overrides_and_adds_no_time_limit():
    env = gymnasium.make(ID, episode_length=LENGTH)
    assert isinstance(env.unwrapped, MarineJaxEnv)
    wrapper, chain = env, []
    while isinstance(wrapper, gymnasium.Wrapper):
        chain.append(type(wrapper).__name__)
        wrapper = wrapper.env
    assert "TimeLimit" not in chain
    assert env.spec.max_episode_steps is None
    assert env.unwrapped.episode_length == LENGTH and env.unwrapped.marine_env.config.episode_length == LENGTH
    assert env.observation_space == gymnasium.spaces.Box(-np.inf, np.inf, (OBS,), np.float32)
    assert env.action_space == gymnasium.spaces.Box(-1.0, 1.0, (ACT,), np.float32)
    assert env.metadata == {"render_modes": ["rgb_array"], "render_fps": 20}
    obs, info = env.reset(seed=0)
    assert obs.shape == (OBS,) and obs.dtype == np.float32
    assert obs.flags.writeable
    assert isinstance(info["position_error"], float)
    with warnings.catch_warnings(record=True) as caught:  # PassiveEnvChecker has nothing to say
        warnings.simplefilter("always")
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert not [str(w.message) for w in caught if "gymnasium" in w.filename]
    assert obs.dtype == np.float32 and isinstance(reward, float)
    assert terminated is False and truncated is False
    assert {"position_error", "heading_error_deg", "reward/position", "nonfinite", "out_of_bounds"} <= set(info)
    assert all(isinstance(v, float) for v in info.values())


def test_make_vec_by_id_uses_the_batched_vector_entry_point():
    envs = gymnasium.make_vec(ID, num_envs=N, episode_length=LENGTH)
    assert isinstance(envs, MarineJaxVectorEnv) and envs.num_envs == N and envs.episode_length == LENGTH
    assert envs.spec.kwargs["vectorization_mode"] == "vector_entry_point"
    assert envs.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP
    assert envs.single_observation_space == gymnasium.spaces.Box(-np.inf, np.inf, (OBS,), np.float32)
    assert envs.single_action_space == gymnasium.spaces.Box(-1.0, 1.0, (ACT,), np.float32)
    assert envs.observation_space.shape == (N, OBS) and envs.observation_space.dtype == np.float32
    assert envs.action_space.shape == (N, ACT)
    obs, infos = envs.reset(seed=0)
    assert obs.shape == (N, OBS) and obs.dtype == np.float32 and obs in envs.observation_space
    obs, reward, terminated, truncated, infos = envs.step(envs.action_space.sample())
    assert obs.shape == (N, OBS) and obs.dtype == np.float32
    assert reward.shape == (N,) and terminated.dtype == np.bool_ and truncated.dtype == np.bool_
    assert infos["position_error"].shape == (N,) and infos["_position_error"].all()


def test_vector_env_equals_single_envs_through_truncation_then_next_step_autoresets(single, vec):
    steps = LENGTH + 3
    actions = random_actions(steps)
    singles = [run_single(single, 10 + i, actions[:, i]) for i in range(N)]
    assert all(len(s) == LENGTH + 1 for s in singles)  # no early termination under these actions

    obs, _ = vec.reset(seed=10)
    vector = [(obs, np.zeros(N), np.zeros(N, bool), np.zeros(N, bool))]
    counters = [vec.elapsed_steps]
    for a in actions:
        vector.append(vec.step(a)[:4])
        counters.append(vec.elapsed_steps)

    for t in range(LENGTH + 1):  # reset, then every step up to and including the truncation
        for i in range(N):
            s_obs, s_rew, s_term, s_trunc = singles[i][t]
            v_obs, v_rew, v_term, v_trunc = (x[i] for x in vector[t])
            np.testing.assert_allclose(v_obs, s_obs, atol=1e-5, err_msg=f"obs, step {t}, env {i}")
            np.testing.assert_allclose(v_rew, s_rew, atol=1e-5, err_msg=f"reward, step {t}, env {i}")
            assert (bool(v_term), bool(v_trunc)) == (s_term, s_trunc), (t, i)
    assert vector[LENGTH][3].all() and not vector[LENGTH][2].any()  # truncated at episode_length
    np.testing.assert_array_equal(counters[LENGTH], LENGTH)

    # NEXT_STEP: the step after the truncation resets every env instead of stepping it.
    obs, reward, terminated, truncated = vector[LENGTH + 1]
    np.testing.assert_array_equal(reward, 0.0)
    assert not terminated.any() and not truncated.any()
    assert obs.shape == (N, OBS) and obs.dtype == np.float32
    np.testing.assert_array_equal(counters[LENGTH + 1], 0)
    np.testing.assert_array_equal(counters[LENGTH + 2], 1)
    np.testing.assert_array_equal(counters[LENGTH + 3], 2)
    assert not np.allclose(obs, vector[0][0])  # a new episode (new target and start), not the first one
    # The documented autoreset key: the k-th autoreset of env i uses fold_in(PRNGKey(seed_i), k).
    kernels = single._kernels
    for i in range(N):
        expected = kernels.reset(jax.random.fold_in(jax.random.PRNGKey(10 + i), 1)).obs
        np.testing.assert_allclose(obs[i], np.asarray(expected), atol=1e-5)
    assert all(r != 0.0 for r in vector[LENGTH + 2][1])  # stepping again after the autoreset


def test_autoreset_step_ignores_the_actions(vec):
    actions = random_actions(LENGTH + 2, seed=1)
    runs = []
    for autoreset_action in (actions[LENGTH], -actions[LENGTH]):
        vec.reset(seed=3)
        out = [vec.step(a)[:2] for a in actions[:LENGTH]]
        out.append(vec.step(autoreset_action)[:2])
        out.append(vec.step(actions[LENGTH + 1])[:2])
        runs.append(out)
    for (obs_a, rew_a), (obs_b, rew_b) in zip(*runs):
        np.testing.assert_array_equal(obs_a, obs_b)
        np.testing.assert_array_equal(rew_a, rew_b)


def test_termination_then_next_step_autoreset_of_only_that_env(single, vec):
    actions = random_actions(4, seed=2)
    single.reset(seed=7)
    single._state = shift_target(single._state)
    obs, reward, terminated, truncated, info = single.step(actions[0, 0])
    assert terminated is True and truncated is False and info["out_of_bounds"] == 1.0

    vec.reset(seed=7)
    vec.step(actions[0])
    vec._carry = vec._carry._replace(state=shift_target(vec._carry.state, index=1))
    _, reward, terminated, truncated, infos = vec.step(actions[1])
    np.testing.assert_array_equal(terminated, [False, True, False])
    assert not truncated.any() and infos["out_of_bounds"][1] == 1.0
    np.testing.assert_array_equal(vec.elapsed_steps, [2, 2, 2])
    obs, reward, terminated, truncated, _ = vec.step(actions[2])  # env 1 resets, the others step
    assert reward[1] == 0.0 and reward[0] != 0.0 and reward[2] != 0.0
    assert not terminated.any() and not truncated.any()
    np.testing.assert_array_equal(vec.elapsed_steps, [3, 0, 3])
    _, _, terminated, _, _ = vec.step(actions[3])
    assert not terminated.any()
    np.testing.assert_array_equal(vec.elapsed_steps, [4, 1, 4])


def test_partial_reset_with_reset_mask(vec):
    first, _ = vec.reset(seed=20)
    for a in random_actions(3, seed=3):
        before, *_ = vec.step(a)
    mask = np.array([True, False, True])
    obs, infos = vec.reset(seed=20, options={"reset_mask": mask})
    np.testing.assert_allclose(obs[mask], first[mask], atol=1e-6)  # same seeds: same first observations
    np.testing.assert_array_equal(obs[1], before[1])  # untouched
    np.testing.assert_array_equal(vec.elapsed_steps, [0, 3, 0])
    np.testing.assert_array_equal(infos["_position_error"], mask)
    with pytest.raises(ValueError, match="reset_mask"):
        vec.reset(options={"reset_mask": np.array([1, 0, 1])})


def test_seeding_same_seed_same_episode_different_seeds_differ(single, vec):
    actions = random_actions(5, seed=4)[:, 0]
    a = run_single(single, 5, actions)
    b = run_single(single, 5, actions)
    for (obs_a, rew_a, *_), (obs_b, rew_b, *_) in zip(a, b):
        np.testing.assert_array_equal(obs_a, obs_b)
        assert rew_a == rew_b
    assert not np.allclose(single.reset(seed=6)[0], a[0][0])

    # Seeding once, then resetting without a seed, is reproducible.
    single.reset(seed=8)
    first = [single.reset()[0] for _ in range(2)]
    single.reset(seed=8)
    again = [single.reset()[0] for _ in range(2)]
    np.testing.assert_array_equal(np.stack(first), np.stack(again))
    assert not np.allclose(first[0], first[1])

    # Vector: an int seed s means seeds s, s+1, ...; a list gives them explicitly.
    from_int, _ = vec.reset(seed=5)
    from_list, _ = vec.reset(seed=[5, 6, 7])
    np.testing.assert_array_equal(from_int, from_list)
    np.testing.assert_allclose(from_int[0], a[0][0], atol=1e-5)
    assert not np.allclose(from_int[0], from_int[1])
    vec.reset(seed=9)
    seedless = vec.reset()[0]
    vec.reset(seed=9)
    np.testing.assert_array_equal(vec.reset()[0], seedless)


def test_an_env_whose_construction_failed_closes_quietly():
    # gymnasium's VectorEnv.__del__ calls close() on an env whose __init__ raised before its renderer
    # existed (stack 2's gymnasium printed an ignored AttributeError for every bad-argument test)
    for cls in (MarineJaxEnv, MarineJaxVectorEnv):
        cls.__new__(cls).close()


def test_errors_are_clear(single, vec):
    single.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(8,\).*got shape \(9,\)"):
        single.step(np.zeros(ACT + 1))
    with pytest.raises(ValueError, match=r"shape \(3, 8\).*got shape \(8,\)"):
        vec.step(np.zeros(ACT))
    with pytest.raises(ValueError, match="unknown env"):
        MarineJaxEnv("Submarine-StationKeeping")
    with pytest.raises(ValueError, match="unknown env"):
        MarineJaxVectorEnv("Submarine-StationKeeping", num_envs=2)
    with pytest.raises(ValueError, match="render_mode"):
        MarineJaxEnv(NAME, render_mode="human", episode_length=LENGTH)
    with pytest.raises(ValueError, match="valid: None, 'rgb_array'"):
        MarineJaxVectorEnv(NAME, num_envs=2, render_mode="depth_array", episode_length=LENGTH)
    # overrides are validated by marinejax.envs.make; an unknown keyword is a TypeError, as in Python
    with pytest.raises(TypeError, match="unknown config key 'episode_lenght'"):
        gymnasium.make(ID, episode_lenght=LENGTH)
    with pytest.raises(TypeError, match="unknown config key 'frameskip'"):
        MarineJaxVectorEnv(NAME, num_envs=2, frameskip=4)
    with pytest.raises(ValueError, match="must be an integer"):
        gymnasium.make(ID, episode_length=2.5)
    with pytest.raises(ValueError, match="autoreset_mode='disabled' is not supported"):
        MarineJaxVectorEnv(NAME, num_envs=2, autoreset_mode="disabled", episode_length=LENGTH)
    with pytest.raises(ValueError, match="num_envs"):
        MarineJaxVectorEnv(NAME, num_envs=0, episode_length=LENGTH)
    with pytest.raises(ValueError, match="seed"):
        vec.reset(seed=[1, 2])
    fresh = MarineJaxEnv(NAME, episode_length=LENGTH)
    with pytest.raises(gymnasium.error.ResetNeeded):
        fresh.step(np.zeros(ACT, np.float32))


def test_registration_covers_every_env_and_is_idempotent():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ids = register_gymnasium_envs()
    assert ids == [gymnasium_id(name) for name in list_envs()]
    for env_id, name in zip(ids, list_envs()):
        spec = gymnasium.spec(env_id)
        assert spec.kwargs == {"env_name": name} and spec.max_episode_steps is None
        assert spec.vector_entry_point == "marinejax.envs.gym_adapter:MarineJaxVectorEnv"


def test_same_step_autoreset_returns_the_new_episode_and_the_final_observation(single):
    """SAME_STEP (TorchRL's mode): the step that ends an episode returns its reward and flags, the next
    episode's first observation, and the last observation in infos["final_obs"]; the episodes are the
    same as with NEXT_STEP (same keys)."""
    same = gymnasium.make_vec(ID, num_envs=N, episode_length=LENGTH, autoreset_mode="same_step")
    nxt = MarineJaxVectorEnv(NAME, num_envs=N, episode_length=LENGTH)
    assert same.autoreset_mode == gymnasium.vector.AutoresetMode.SAME_STEP == same.metadata["autoreset_mode"]
    # the enum member, as Gymnasium documents it and as the error message offers (its value is "SameStep")
    by_enum = gymnasium.make_vec(ID, num_envs=N, episode_length=LENGTH, autoreset_mode=gymnasium.vector.AutoresetMode.SAME_STEP)
    assert by_enum.autoreset_mode == gymnasium.vector.AutoresetMode.SAME_STEP
    by_enum.close()
    assert nxt.autoreset_mode == gymnasium.vector.AutoresetMode.NEXT_STEP
    actions = random_actions(2 * LENGTH + 2, seed=3)
    obs_s, _ = same.reset(seed=7)
    obs_n, _ = nxt.reset(seed=7)
    np.testing.assert_array_equal(obs_s, obs_n)
    t = 0
    for step in range(LENGTH):
        obs_s, rew_s, term_s, trunc_s, info_s = same.step(actions[t])
        obs_n, rew_n, term_n, trunc_n, info_n = nxt.step(actions[t])
        t += 1
        np.testing.assert_array_equal(rew_s, rew_n)
        np.testing.assert_array_equal(trunc_s, trunc_n)
        if step < LENGTH - 1:
            np.testing.assert_array_equal(obs_s, obs_n)
            assert "final_obs" not in info_s
    assert trunc_s.all() and not term_s.any()
    np.testing.assert_array_equal(info_s["final_obs"], obs_n)  # the last observation of the episode
    assert info_s["_final_obs"].all() and info_s["_final_info"].all()
    np.testing.assert_array_equal(info_s["final_info"]["position_error"], info_n["position_error"])
    first_s = obs_s
    obs_n, rew_n, _, trunc_n, _ = nxt.step(actions[t])  # NEXT_STEP resets one call later
    np.testing.assert_array_equal(first_s, obs_n)
    assert (rew_n == 0).all() and same.elapsed_steps.tolist() == [0] * N
    obs_s, *_ = same.step(actions[t + 1])
    obs_n, *_ = nxt.step(actions[t + 1])
    np.testing.assert_array_equal(obs_s, obs_n)


def test_rgb_array_rendering_in_a_child_process_with_egl():
    """render_mode="rgb_array" frames of the documented size; MuJoCo needs MUJOCO_GL=egl headless,
    which must be set before it is imported: hence a child process."""
    import os
    import subprocess
    import sys

    code = f"""
import gymnasium, numpy as np
import marinejax
env = gymnasium.make("{ID}", render_mode="rgb_array", episode_length={LENGTH})
env.reset(seed=0)
a = env.render()
env.step(np.ones(8, np.float32))
b = env.render()
vec = gymnasium.make_vec("{ID}", num_envs=2, render_mode="rgb_array", render_width=64, render_height=48, episode_length={LENGTH})
vec.reset(seed=0)
frames = vec.render()
print(a.shape, a.dtype, int(a.std() > 5), int(np.abs(a.astype(int) - b.astype(int)).sum() > 0), len(frames), frames[0].shape)
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "MUJOCO_GL": "egl"})
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip().splitlines()[-1] == "(480, 640, 3) uint8 1 1 2 (48, 64, 3)"


def test_module_prefixed_id_imports_marinejax_itself():
    import subprocess
    import sys

    code = f"import gymnasium; env = gymnasium.make('marinejax:{ID}', episode_length=5); print(env.reset(seed=0)[0].shape)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0 and proc.stdout.strip() == f"({OBS},)", proc.stderr[-2000:]


def test_async_vector_env_fails_clearly_when_forked_and_works_with_spawn():
    import subprocess
    import sys

    code = f"""
import gymnasium, marinejax, numpy as np
import jax.numpy as jnp
jnp.zeros(1).block_until_ready()  # JAX has started its threads
try:
    gymnasium.make_vec("{ID}", num_envs=2, vectorization_mode="async", vector_kwargs={{"context": "fork"}}, episode_length=5)
except Exception:  # the child's RuntimeError ends it; the parent sees the broken pipe
    print("fork: failed")
envs = gymnasium.make_vec("{ID}", num_envs=2, vectorization_mode="async", vector_kwargs={{"context": "spawn"}}, episode_length=5)
obs, _ = envs.reset(seed=0)
obs, *_ = envs.step(np.zeros((2, 8), np.float32))
print("spawn:", obs.shape)
envs.close()
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().splitlines()[-2:] == ["fork: failed", f"spawn: (2, {OBS})"], proc.stdout
    assert "cannot run in a process forked after JAX started" in proc.stderr  # the child says why
