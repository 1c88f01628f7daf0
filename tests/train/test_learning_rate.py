"""PPO's "linear" learning-rate schedule and warmup (`train/ppo.py`): their values, and that the rate Brax's PPO is
handed drives the optimizer Brax builds (gradient clipping, then Adam) update by update, resumed runs
included. The CLI tests train and resume with it through Brax."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from marinejax.errors import UserError
from marinejax.train import ppo

CONFIG = ppo.Config(num_timesteps=1_024_000, learning_rate=1e-3, learning_rate_schedule="linear", decay_start=0.5,
                    final_learning_rate=1e-4, batch_size=256, unroll_length=10, num_minibatches=4, num_updates_per_batch=4)
UPDATES_PER_STEP = 16  # num_updates_per_batch × num_minibatches
ENV_STEPS_PER_STEP = 10_240  # batch_size × unroll_length × num_minibatches


def test_the_linear_schedule_holds_the_rate_then_falls_linearly_to_the_final_rate():
    at = lambda steps: float(ppo.learning_rate_at(CONFIG, steps))  # noqa: E731
    np.testing.assert_allclose([at(0), at(512_000), at(768_000), at(1_024_000), at(2_000_000)],
                               [1e-3, 1e-3, 5.5e-4, 1e-4, 1e-4], rtol=1e-6)
    constant = ppo.Config(learning_rate=1e-3)
    assert float(ppo.learning_rate_at(constant, 10**9)) == pytest.approx(1e-3)
    assert ppo.brax_learning_rate(constant, 0) == 1e-3 and not callable(ppo.brax_learning_rate(constant, 0))


def test_the_warmup_raises_the_rate_linearly_from_zero_then_hands_over_to_the_schedule():
    warm = dataclasses.replace(CONFIG, warmup=0.25)  # 256,000 env steps
    at = lambda steps: float(ppo.learning_rate_at(warm, steps))  # noqa: E731
    np.testing.assert_allclose([at(0), at(64_000), at(128_000), at(256_000), at(512_000), at(768_000), at(1_024_000)],
                               [0.0, 2.5e-4, 5e-4, 1e-3, 1e-3, 5.5e-4, 1e-4], rtol=1e-6, atol=1e-12)
    constant = ppo.Config(num_timesteps=1_024_000, learning_rate=1e-3, warmup=0.5, batch_size=256, unroll_length=10,
                          num_minibatches=4, num_updates_per_batch=4)
    rate = ppo.brax_learning_rate(constant, 0)
    assert callable(rate) and float(jnp.array(rate)) == 0.0
    steps = adam_steps(rate, 1_600)
    np.testing.assert_allclose(steps[[0, 400, 800, 1_599]], [0.0, 5e-4, 1e-3, 1e-3], rtol=1e-4, atol=1e-12)


def adam_steps(rate, updates: int) -> np.ndarray:
    """The step size of each of `updates` updates of Brax's PPO optimizer with `rate`: with a constant
    gradient Adam's bias-corrected step is the learning rate itself."""
    optimizer = optax.chain(optax.clip_by_global_norm(1.0), optax.adam(learning_rate=rate))
    params, grads = jnp.zeros(1), jnp.full(1, 1e-3)

    def step(state, _):
        update, state = optimizer.update(grads, state)
        return state, -update[0]

    return np.asarray(jax.lax.scan(step, optimizer.init(params), None, length=updates)[1])


@pytest.mark.parametrize("steps_done", [0, 614_400])
def test_the_rate_handed_to_brax_drives_adam_update_by_update_and_a_resumed_run_continues_it(steps_done):
    rate = ppo.brax_learning_rate(CONFIG, steps_done)
    # Brax records its learning rate with jnp.array: the float is the rate at the call's start
    assert float(jnp.array(rate)) == pytest.approx(float(ppo.learning_rate_at(CONFIG, steps_done)))
    updates = 1_600 - steps_done // ENV_STEPS_PER_STEP * UPDATES_PER_STEP  # to 1,024,000 env steps
    steps = adam_steps(rate, updates)
    env_steps = steps_done + np.arange(updates) / UPDATES_PER_STEP * ENV_STEPS_PER_STEP
    expected = [float(ppo.learning_rate_at(CONFIG, s)) for s in env_steps]
    np.testing.assert_allclose(steps, expected, rtol=1e-4)
    assert steps[-1] == pytest.approx(1e-4, rel=2e-2) and steps.max() <= 1e-3 * (1 + 1e-4)


@pytest.mark.parametrize("overrides,message", [
    ({"decay_start": 1.0}, "'decay_start' must be in [0, 1)"),
    ({"final_learning_rate": 2e-3}, "'final_learning_rate' must be between 0 and learning_rate (0.001), got 0.002"),
    ({"learning_rate_schedule": "cosine"}, "must be one of ['none', 'adaptive_kl', 'linear'], got 'cosine'"),
    ({"warmup": 1.0}, "'warmup' must be in [0, 1) (a fraction of num_timesteps), got 1.0"),
    ({"warmup": 0.1, "learning_rate_schedule": "adaptive_kl"}, "'warmup' works with learning_rate_schedule 'none' or 'linear'"),
])
def test_bad_schedule_settings_name_the_value_and_the_valid_range(overrides, message):
    with pytest.raises(UserError) as err:
        dataclasses.replace(CONFIG, **overrides)
    assert message in str(err.value)
