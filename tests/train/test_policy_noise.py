"""The PPO policy's exploration std (`ppo.Config.init_noise_std`, `max_noise_std`): Brax's
tanh-normal policy takes its std from the network's output, std = softplus(x) + 0.001, and ignores
Brax's own init_noise_std; ours shift and bound x, and leave the location (the deterministic policy)
alone."""

import json
import re
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from marinejax.errors import UserError
from marinejax.train import ppo

OBS, ACT = 10, 3


def _outputs(config, scale=1.0):
    """The policy network's output (location, std parameter x) for a batch of observations, with
    the network's weights multiplied by `scale` (large weights drive x far out)."""
    networks = ppo.network_factory(config, OBS)(OBS, ACT)
    params = jax.tree.map(lambda w: w * scale, networks.policy_network.init(jax.random.PRNGKey(0)))
    obs = jax.random.normal(jax.random.PRNGKey(1), (256, OBS)) * 3.0
    out = networks.policy_network.apply(None, params, obs)
    return out[:, :ACT], out[:, ACT:]


def _std(x):
    return jax.nn.softplus(x) + 0.001  # Brax's NormalTanhDistribution


def test_brax_ignores_its_own_init_noise_std_for_the_tanh_normal_policy():
    # why the setting is ours: Brax's kwarg changes nothing in its default tanh-normal network
    from brax.training.agents.ppo import networks as ppo_networks

    outs = []
    for std in (0.5, 5.0):
        net = ppo_networks.make_ppo_networks(OBS, ACT, policy_hidden_layer_sizes=(64, 64), init_noise_std=std).policy_network
        outs.append(net.apply(None, net.init(jax.random.PRNGKey(0)), jnp.ones((1, OBS))))
    assert jnp.array_equal(outs[0], outs[1])


def test_defaults_leave_brax_network_unchanged_and_settings_shift_and_bound_the_std_only():
    from brax.training import distribution

    plain_loc, plain_x = _outputs(ppo.Config())
    # `_std` is the std Brax's tanh-normal makes of x (the std at x = 0 without a shift: 0.694)
    brax_std = distribution.NormalTanhDistribution(event_size=ACT).create_dist(jnp.concatenate([plain_loc, plain_x], axis=-1)).scale
    np.testing.assert_allclose(brax_std, _std(plain_x), rtol=1e-6)
    assert float(_std(jnp.zeros(()))) == pytest.approx(0.6941, abs=1e-4)

    loc, x = _outputs(ppo.Config(init_noise_std=0.3))
    assert jnp.array_equal(loc, plain_loc)
    np.testing.assert_allclose(_std(x - plain_x), 0.3, rtol=1e-5)  # a constant shift: x = 0 gives 0.3
    assert float(jnp.max(jnp.abs(plain_x))) > 0.05  # the batch spans more than x = 0

    loc, x = _outputs(ppo.Config(max_noise_std=1.0), scale=30.0)  # weights large enough to send the std to tens
    big_loc, big_x = _outputs(ppo.Config(), scale=30.0)
    assert jnp.array_equal(loc, big_loc)
    assert float(jnp.max(_std(big_x))) > 10.0
    assert 0.99 < float(jnp.max(_std(x))) <= 1.0 + 1e-6  # bounded, and the bound is reached
    small = _std(big_x) < 0.3  # well under the bound the std is nearly unchanged
    assert bool(jnp.any(small))
    np.testing.assert_allclose(_std(x)[small], _std(big_x)[small], rtol=0.02)
    # both together: the shifted std under the bound
    _, x = _outputs(ppo.Config(init_noise_std=0.5, max_noise_std=1.0), scale=30.0)
    assert float(jnp.max(_std(x))) <= 1.0 + 1e-6


@pytest.mark.parametrize("settings, message", [
    ({"init_noise_std": -0.1}, "ppo 'init_noise_std' must be 0 (Brax's network unchanged) or a std > 0.001, got -0.1"),
    ({"max_noise_std": 0.001}, "ppo 'max_noise_std' must be 0 (Brax's network unchanged) or a std > 0.001, got 0.001"),
    ({"max_noise_std": float("inf")}, "got inf"),
    ({"init_noise_std": 1.0, "max_noise_std": 0.8}, "ppo 'init_noise_std' (1.0) must be below 'max_noise_std' (0.8)"),
])
def test_bad_noise_settings_are_user_errors(settings, message):
    with pytest.raises(UserError, match=re.escape(message)):
        ppo.Config(**settings)


def test_a_config_written_before_the_settings_took_effect_drops_the_ignored_value():
    # a shipped policy's config.json records the init_noise_std Brax ignored (0.5)
    import marinejax

    shipped = json.loads((Path(marinejax.__file__).parent / "policies" / "BlueROV2-LemniscateTracking" / "config.json").read_text())
    recorded = shipped["ppo"]
    assert recorded["init_noise_std"] == 0.5 and "max_noise_std" not in recorded
    config = ppo.Config.from_dict(recorded)
    assert config.init_noise_std == 0.0 and config.max_noise_std == 0.0
    assert ppo.Config.from_dict(ppo.Config(init_noise_std=0.4, max_noise_std=1.0).__dict__) == ppo.Config(init_noise_std=0.4, max_noise_std=1.0)
