"""Where a PPO training's time goes: `marinejax bench training ENV --profile`.

Brax's PPO training step (`brax.training.agents.ppo.train`) collects
`batch_size · num_minibatches / num_envs` unrolls of `unroll_length` steps of `num_envs` envs with
the stochastic policy, updates the observation normalizer, then runs `num_updates_per_batch` epochs
of `num_minibatches` minibatch updates (PPO loss and its gradient, then Adam); after every training
epoch it evaluates the policy (`num_eval_envs` deterministic episodes). Here each part is jitted
alone with the env's tuned settings and timed after compilation (the best of several calls,
`common.time_calls`). Then the same settings train for real for a few steps, and Brax's own clocks
give the training step as it runs in `ppo.train` (`training/walltime`) and an evaluation
(`eval/epoch_eval_time`). "other" is the measured step minus its parts: the scans, the batch's
shuffling, host transfers (negative where XLA fuses the parts better than it runs them alone).
The whole recipe's wall time is projected from these and the compilation the short run measured
(its wall time minus its steady epochs and evaluations). A recipe that trains on several CPU devices
(`cpu_devices`) has its training step measured on them too, and its projection uses that step.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from typing import Any

PARTS = ("env", "policy", "normalizer", "loss_and_gradient", "optimizer")
PART_LABELS = {
    "env": "env steps (physics, sensors, task)",
    "policy": "policy inference (stochastic actions)",
    "normalizer": "observation normalizer update",
    "loss_and_gradient": "PPO loss and gradient",
    "optimizer": "optimizer (gradient clip, Adam)",
    "other": "other (scans, shuffling, transfers)",
}
TARGET_EPOCH_SECONDS = 2.0  # length of each training epoch of the short real run
SHORT_EPOCHS = 3  # training epochs of the short real run (the first two compile)


def _parts(env, agent, network_factory) -> dict[str, Any]:
    """Each part of a training step jitted alone and timed: its seconds per training step (one
    call's best time × the calls one step makes)."""
    import jax
    import jax.numpy as jnp
    import optax
    from brax.training import acting
    from brax.training.acme import running_statistics, specs
    from brax.training.agents.ppo import losses as ppo_losses
    from brax.training.agents.ppo import networks as ppo_networks

    from marinejax.benchmarks.common import time_calls
    from marinejax.envs import wrap_for_training

    wrapped = wrap_for_training(env, episode_length=env.config.episode_length)
    key = jax.random.PRNGKey(agent.seed)
    state = jax.jit(wrapped.reset)(jax.random.split(key, agent.num_envs))
    obs_shape = jax.tree.map(lambda x: x.shape[1:], state.obs)
    network = network_factory(obs_shape, env.action_size, preprocess_observations_fn=running_statistics.normalize)
    k_policy, k_value, k_unroll = jax.random.split(key, 3)
    params = ppo_losses.PPONetworkParams(policy=network.policy_network.init(k_policy),
                                         value=network.value_network.init(k_value))
    normalizer = running_statistics.init_state(jax.tree.map(lambda x: specs.Array(x.shape[-1:], jnp.dtype("float32")), state.obs))
    policy = ppo_networks.make_inference_fn(network)((normalizer, params.policy, params.value))

    # one unroll as Brax collects it, for the transitions the loss is timed on
    fields = ("truncation", "episode_metrics", "episode_done")
    _, data = jax.jit(functools.partial(acting.generate_unroll, wrapped, policy=policy, unroll_length=agent.unroll_length,
                                        extra_fields=fields))(state, key=k_unroll)
    data = jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1), data)  # (num_envs, unroll_length, ...)
    minibatch = jax.tree.map(lambda x: jnp.concatenate([x] * max(1, agent.batch_size // agent.num_envs))[: agent.batch_size], data)
    actions = jnp.zeros((agent.num_envs, env.action_size))

    @jax.jit
    def env_unroll(s):
        return jax.lax.scan(lambda s, _: (wrapped.step(s, actions), None), s, length=agent.unroll_length)[0]

    @jax.jit
    def policy_unroll(obs, k):
        return jax.lax.scan(lambda k, _: (jax.random.split(k)[0], policy(obs, k)[0]), k, length=agent.unroll_length)[1]

    @jax.jit
    def normalizer_update(n, observations):
        return running_statistics.update(n, observations)

    loss = functools.partial(ppo_losses.compute_ppo_loss, ppo_network=network, entropy_cost=agent.entropy_cost,
                             discounting=agent.discounting, reward_scaling=agent.reward_scaling,
                             gae_lambda=agent.gae_lambda, clipping_epsilon=agent.clipping_epsilon)
    grad = jax.jit(jax.value_and_grad(loss, has_aux=True))
    optimizer = optax.chain(optax.clip_by_global_norm(agent.max_grad_norm), optax.adam(agent.learning_rate))
    opt_state = optimizer.init(params)
    (_, _), grads = grad(params, normalizer, minibatch, key)

    @jax.jit
    def apply(p, o, g):
        updates, o = optimizer.update(g, o, p)
        return optax.apply_updates(p, updates), o

    all_observations = jax.tree.map(lambda x: jnp.concatenate([x] * (agent.batch_size * agent.num_minibatches // agent.num_envs)),
                                    data.observation)
    times = time_calls({
        "env": lambda: env_unroll(state),
        "policy": lambda: policy_unroll(state.obs, key),
        "normalizer": lambda: normalizer_update(normalizer, all_observations),
        "loss_and_gradient": lambda: grad(params, normalizer, minibatch, key),
        "optimizer": lambda: apply(params, opt_state, grads),
    })
    unrolls = agent.batch_size * agent.num_minibatches // agent.num_envs
    updates = agent.num_minibatches * agent.num_updates_per_batch
    calls = {"env": unrolls, "policy": unrolls, "normalizer": 1, "loss_and_gradient": updates, "optimizer": updates}
    return {name: times[name]["seconds"] * calls[name] for name in PARTS}


def _measured(env, agent, module, steps_per_training_step: int, step_estimate: float, devices: int = 1) -> dict[str, float]:
    """A short real training with Brax (the same settings): seconds per training step, per
    evaluation, and the compilation and set-up, from Brax's clocks and the wall clock. Brax's first
    two training epochs and first two evaluations each compile (with jax ≥ 0.10 the state it places
    on the devices is sharded unlike what its pmap returns: google/brax#674), so the steady epoch
    and evaluation are the last of SHORT_EPOCHS. `devices`: the local devices the batch is split over."""
    from marinejax.envs import wrap_for_training

    per_epoch = max(1, math.ceil(TARGET_EPOCH_SECONDS / max(step_estimate, 1e-6)))
    short = dataclasses.replace(agent, num_evals=SHORT_EPOCHS + 1, num_timesteps=SHORT_EPOCHS * per_epoch * steps_per_training_step)
    records = []
    start = time.perf_counter()
    module.run(env, short, num_timesteps=short.num_timesteps, seed=agent.seed, wrap_env_fn=wrap_for_training,
               progress_fn=lambda step, metrics: records.append({k: float(metrics[k]) for k in ("eval/epoch_eval_time", "training/walltime")
                                                                 if k in metrics}),
               save_fn=lambda step, params: None, restore=None, devices=devices, checkpoint_dir=None)
    total = time.perf_counter() - start
    if len(records) != SHORT_EPOCHS + 1:
        raise RuntimeError(f"the short training reported {len(records)} evaluations, expected {SHORT_EPOCHS + 1}")
    epoch = records[-1]["training/walltime"] - records[-2]["training/walltime"]
    evaluation = records[-1]["eval/epoch_eval_time"]
    return {"training_step": epoch / per_epoch, "evaluation": evaluation,
            "compilation": max(total - SHORT_EPOCHS * epoch - (SHORT_EPOCHS + 1) * evaluation, 0.0)}


def profile(env_name: str, agent_overrides: dict | None = None, env_overrides: dict | None = None) -> dict[str, Any]:
    """Profile the PPO training of `env_name` with its tuned settings (plus overrides): the parts of
    a training step (s per step and share of the measured step, summing to 1 with "other"), the
    measured step, an evaluation, the compilation, and the whole recipe projected from them."""
    import jax

    from marinejax.train.hyperparams import build_env, tuned_config, with_overrides

    config = with_overrides(tuned_config(env_name, "ppo"), agent=agent_overrides or {}, env=env_overrides or {})
    agent, module = config.agent, config.module
    env = build_env(config)
    parts = _parts(env, agent, module.env_network_factory(agent, env))
    steps_per_training_step = agent.batch_size * agent.num_minibatches * agent.unroll_length
    measured = _measured(env, agent, module, steps_per_training_step, sum(parts.values()))
    step = measured["training_step"]
    parts["other"] = step - sum(parts.values())
    # a recipe with several CPU devices: the same step on them, in this run (the parts are one device's)
    cpu_devices = min(agent.cpu_devices, jax.local_device_count()) if jax.default_backend() == "cpu" else 1
    on_devices = measured
    if cpu_devices > 1:
        on_devices = _measured(env, agent, module, steps_per_training_step, step / cpu_devices, devices=cpu_devices)
    training_steps = math.ceil(agent.num_timesteps / steps_per_training_step)
    recipe = {"training": training_steps * on_devices["training_step"], "evaluations": agent.num_evals * on_devices["evaluation"],
              "compilation": on_devices["compilation"]}
    whole = sum(recipe.values())
    return {
        "env": env_name,
        "settings": {k: getattr(agent, k) for k in ("num_envs", "unroll_length", "batch_size", "num_minibatches",
                                                     "num_updates_per_batch", "policy_hidden", "value_hidden",
                                                     "num_timesteps", "num_evals", "num_eval_envs")},
        "env_steps_per_training_step": steps_per_training_step,
        "parts_s": parts,
        "shares": {name: t / step for name, t in parts.items()},
        "training_step_s": step,
        "training_env_steps_per_s": steps_per_training_step / step,
        "env_alone_env_steps_per_s": steps_per_training_step / parts["env"],
        "evaluation_s": measured["evaluation"],
        "cpu_devices": cpu_devices,
        "training_step_on_cpu_devices_s": on_devices["training_step"],
        "cpu_devices_speedup": step / on_devices["training_step"],
        "recipe_s": recipe,
        "recipe_shares": {name: t / whole for name, t in recipe.items()},
        "recipe_total_s": whole,
    }


def report(result: dict[str, Any]) -> str:
    """The profile as a table (what `bench training --profile` prints)."""
    s = result["settings"]
    lines = [
        f"{result['env']}: PPO training step = {result['env_steps_per_training_step']:,} env steps "
        f"({s['num_envs']} envs × {s['unroll_length']} steps × {s['batch_size'] * s['num_minibatches'] // s['num_envs']} unrolls; "
        f"{s['num_updates_per_batch']} epochs of {s['num_minibatches']} minibatches; networks {tuple(s['policy_hidden'])} / {tuple(s['value_hidden'])})",
        f"  {'part':42s} {'s per step':>11s} {'share':>7s}",
    ]
    for name, t in result["parts_s"].items():
        lines.append(f"  {PART_LABELS[name]:42s} {t:11.4f} {100 * result['shares'][name]:6.1f} %")
    lines.append(f"  {'training step, measured in ppo.train':42s} {result['training_step_s']:11.4f} {100.0:6.1f} %")
    lines.append(f"  training: {result['training_env_steps_per_s']:,.0f} env steps/s; the env alone: "
                 f"{result['env_alone_env_steps_per_s']:,.0f} env steps/s "
                 f"(training runs at {100 * result['training_env_steps_per_s'] / result['env_alone_env_steps_per_s']:.0f} % of the env's rate)")
    lines.append(f"  one evaluation ({s['num_eval_envs']} episodes): {result['evaluation_s']:.2f} s")
    n = result["cpu_devices"]
    if n > 1:
        lines.append(f"  the recipe's {n} CPU devices: training step {result['training_step_on_cpu_devices_s']:.4f} s, "
                     f"{result['cpu_devices_speedup']:.2f}× the one device's above")
    r, sh = result["recipe_s"], result["recipe_shares"]
    lines.append(f"  whole recipe ({s['num_timesteps']:,} env steps, {s['num_evals']} evaluations, {n} device(s)), projected: "
                 f"{result['recipe_total_s']:.0f} s = training {r['training']:.0f} s ({100 * sh['training']:.0f} %) + "
                 f"evaluations {r['evaluations']:.0f} s ({100 * sh['evaluations']:.0f} %) + "
                 f"compilation and set-up {r['compilation']:.0f} s ({100 * sh['compilation']:.0f} %)")
    return "\n".join(lines)
