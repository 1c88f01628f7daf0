"""Controllers and the one closed-loop rollout."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import marinejax as mj
from marinejax.control import policy_controller, random_controller, rollout, run_steps, sequence_controller

STEPS = 6


@pytest.fixture(scope="module")
def env():
    return mj.make("BlueROV2Heavy-StationKeeping", episode_length=40)


def manual(env, key, policy, steps):
    """The loop written out: reset, then step with the policy's action on the current observation."""
    step = jax.jit(lambda s: env.step(s, policy(s.obs)))
    s = jax.jit(env.reset)(key)
    out = []
    for _ in range(steps):
        s = step(s)
        out.append(s.obs)
    return jnp.stack(out)


def test_rollout_of_a_policy_is_the_plain_closed_loop(env):
    policy = lambda obs: jnp.tanh(obs[:8])  # noqa: E731  (any function of the observation)
    keys = jax.random.split(jax.random.PRNGKey(3), 2)
    final, obs = rollout(env, policy_controller(policy), keys, STEPS, record=lambda s: s.obs)
    assert obs.shape == (2, STEPS, env.observation_size)
    for i in range(2):
        np.testing.assert_allclose(np.asarray(obs[i]), np.asarray(manual(env, keys[i], policy, STEPS)), atol=1e-5)
    np.testing.assert_allclose(np.asarray(final.obs), np.asarray(obs[:, -1]))
    default_final, _ = rollout(env, policy_controller(policy), keys[:1])
    assert float(default_final.info["time"][0]) == pytest.approx(40 * env.config.control_dt)  # episode_length steps


def test_random_controller_is_reproducible_and_in_range(env):
    controller = random_controller(env.action_size)
    actions = []
    carry = controller.init(jax.random.PRNGKey(0))
    for _ in range(50):
        a, carry = controller.act(carry, None, None)
        actions.append(a)
    actions = np.asarray(actions)
    assert actions.shape == (50, 8) and actions.min() >= -1 and actions.max() <= 1 and actions.std() > 0.4
    again, _ = controller.act(controller.init(jax.random.PRNGKey(0)), None, None)
    np.testing.assert_array_equal(actions[0], np.asarray(again))


def test_sequence_controller_plays_its_actions_then_holds_the_last(env):
    seq = jnp.stack([jnp.full(8, 0.1 * k) for k in range(3)])
    controller = sequence_controller(seq)
    state = jax.jit(env.reset)(jax.random.PRNGKey(1))
    run = jax.jit(lambda s: run_steps(env, controller, s, controller.init(None), 5, record=lambda t: t.info["last_action"]))
    _, carry, actions = run(state)
    np.testing.assert_allclose(np.asarray(actions[:, 0]), [0.0, 0.1, 0.2, 0.2, 0.2], atol=1e-6)
    assert int(carry) == 5
    with pytest.raises(mj.UserError, match=r"shape \(steps, action_size\)"):
        sequence_controller(jnp.zeros(8))
