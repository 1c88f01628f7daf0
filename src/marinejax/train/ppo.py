"""PPO (Brax's `brax.training.agents.ppo`): its settings, networks, training call, checkpoints and
deterministic policy. Every algorithm module (`ppo`, `sac`) has the same names:

  Config                     frozen dataclass of the algorithm's settings (num_timesteps, num_envs, seed, ...)
  NETWORK_CONFIG             file name of the network config inside a checkpoint directory
  network_factory(config, observation_size, mirror=None)
  env_network_factory(config, env)  the same for an env (its observation size and mirror)
  run(env, config, **common) Brax's train function with our settings (`runner.train` passes `common`)
  save(path, step, params, env, config) / load(path)
  policy(config, env, params) deterministic policy fn observation → action in [−1, 1]
"""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path
from typing import Any, Callable, Mapping

from marinejax.errors import UserError
from marinejax.train.brax_agents import deterministic_policy, save_checkpoint
from marinejax.train.curves import BEST_ON

NETWORK_CONFIG = "ppo_network_config.json"
# Brax's learning-rate schedules: "none" (constant `learning_rate`) or "adaptive_kl" (after every
# update epoch the rate is divided by 1.5 where the policy's mean KL divergence exceeded 2 ×
# `desired_kl` and multiplied by 1.5 where it fell under half of it, within 1e-5–1e-2; the schedule
# of rsl_rl's legged-robot PPO); and ours, "linear": `learning_rate` until `decay_start` of the run's
# env steps, then falling linearly to `final_learning_rate` at `num_timesteps` (`learning_rate_at`).
# With "none" and "linear", `warmup` > 0 raises the rate linearly from 0 over that fraction of the run
# first (the rate is the schedule's times min(1, steps / (warmup × num_timesteps))).
LEARNING_RATE_SCHEDULES = ("none", "adaptive_kl", "linear")
_MIN_STD = 0.001  # Brax's NormalTanhDistribution: std = softplus(x) + min_std


@dataclasses.dataclass(frozen=True)
class Config:
    """Arguments of `brax.training.agents.ppo.train` (see its docstring), plus network sizes and the
    CPU devices it trains on."""

    num_timesteps: int = 3_000_000
    num_envs: int = 256
    unroll_length: int = 20
    batch_size: int = 256
    num_minibatches: int = 8
    num_updates_per_batch: int = 4
    learning_rate: float = 3e-4  # the initial rate with "adaptive_kl" and "linear"
    learning_rate_schedule: str = "none"  # LEARNING_RATE_SCHEDULES
    desired_kl: float = 0.01  # the KL divergence "adaptive_kl" aims at, per update
    decay_start: float = 0.5  # "linear": the fraction of num_timesteps after which the rate falls
    final_learning_rate: float = 0.0  # "linear": the rate at num_timesteps
    warmup: float = 0.0  # "none" and "linear": the fraction of num_timesteps over which the rate rises from 0
    entropy_cost: float = 1e-3
    discounting: float = 0.97
    gae_lambda: float = 0.95
    clipping_epsilon: float = 0.2
    reward_scaling: float = 1.0
    max_grad_norm: float = 1.0
    normalize_observations: bool = True
    # Steps of `num_envs` envs under uniformly random actions whose observations initialise the
    # observation normalizer before training (0: Brax's start, mean 0 and std 1). Brax's first rollout
    # reads raw observations, and its first update re-normalises them with that rollout's statistics
    # before the policy update, whose importance ratios then compare two different policies (its
    # logged KL 0.7-1.7 over the first 0.5 M steps of the torpedo's path runs, 0.01-0.02 after).
    # With `init_from`: the statistics of the observation fields its source lacks (`widen_inputs`).
    normalizer_warmup: int = 0
    # A run directory, a checkpoint inside one, or the env name of a shipped policy (e.g.
    # "Remus100-CircleFollowing") whose best checkpoint starts this run: its observation normalizer,
    # policy and value networks; the optimizer and the step count start anew (a curriculum: the REMUS
    # 100's helix, lemniscate, waypoints and docking start from its circle policy). Its actions must
    # be this env's and mean the same, or be carried out by this vehicle's actuators each following one
    # source action (`action_map`: the four-fin variant from the REMUS 100's policies), its networks
    # have this config's sizes and symmetry, and its observation fields be among this env's, with
    # their sizes: fields this env adds (the docking's `dock`) enter with first-layer weights 0, so the
    # run starts from the source's policy, and normalizer statistics from `normalizer_warmup` steps,
    # which must then be > 0. "": from scratch.
    init_from: str = ""
    # The exploration noise. Brax's policy is a tanh-normal whose std (before the tanh) is an output
    # of the policy network, softplus(x) + 0.001 (about 0.69 at initialisation), and ignores Brax's own
    # init_noise_std. `init_noise_std` > 0 shifts x so that the std at x = 0 is that value;
    # `max_noise_std` > 0 bounds it smoothly (x is replaced by min(x, c) smoothed, c where the std is
    # that value): in the torpedo's path-following runs it grew to 2-14 within 0.5 M steps, highest
    # on the seeds that failed; bounded, fewer lemniscate seeds failed, not fewer helix seeds
    # (docs/results.md). 0: Brax's network unchanged. Both act on the stochastic training policy
    # only: the deterministic policy (tanh of the location), evaluation and export do not change.
    init_noise_std: float = 0.0
    max_noise_std: float = 0.0
    policy_hidden: tuple[int, ...] = dataclasses.field(default=(64, 64), metadata={"variable_length": True})
    value_hidden: tuple[int, ...] = dataclasses.field(default=(64, 64), metadata={"variable_length": True})
    num_evals: int = 20
    num_eval_envs: int = 64
    seed: int = 0
    # On a CPU-only host: the JAX devices the host's cores are split into, each stepping and
    # updating its share of the envs in parallel (Brax's pmap; `runner.use_cpu_devices`). Part of
    # the recipe because the random streams, and so the results, depend on it. Ignored on GPU/TPU.
    cpu_devices: int = 1
    # A mirror-equivariant policy (`envs.symmetry`): the action in the mirror image of a situation is
    # the mirror image of the action, by construction (the network's output averaged with the
    # reflected output for the reflected observation). Both turning directions are learned as one.
    mirror_symmetric: bool = False
    # The training evaluations fly the same `num_eval_envs` episodes every time (Brax draws new ones
    # each time), so that the best checkpoint is the best policy on those episodes rather than the one
    # whose episodes were easiest. Training itself is unchanged. The episodes are the same for every
    # run and seed: their key is a constant of the compiled evaluation, so one per seed would compile
    # it anew for each seed (about 20 s here).
    fixed_eval_episodes: bool = False
    # The best checkpoint (best.json): the lowest window error ("window_error"), or ("targets") the one
    # nearest to meeting every one of the task's targets (`MarineEnv.targets`: the autopilot's depth,
    # heading and speed), so that it cannot be one that trades the speed for the depth.
    best_on: str = "window_error"

    def __post_init__(self):
        for name in ("num_timesteps", "num_envs", "unroll_length", "batch_size", "num_minibatches",
                     "num_updates_per_batch", "num_evals", "num_eval_envs", "cpu_devices"):
            if getattr(self, name) < 1:
                raise UserError(f"ppo '{name}' must be >= 1, got {getattr(self, name)}")
        if (self.batch_size * self.num_minibatches) % self.num_envs:
            raise UserError(
                f"ppo batch_size * num_minibatches ({self.batch_size} * {self.num_minibatches}) must be a "
                f"multiple of num_envs ({self.num_envs})"
            )
        for name in ("learning_rate", "discounting", "gae_lambda", "clipping_epsilon", "reward_scaling"):
            if not getattr(self, name) > 0:
                raise UserError(f"ppo '{name}' must be > 0, got {getattr(self, name)}")
        if self.best_on not in BEST_ON:
            raise UserError(f"ppo 'best_on' must be one of {list(BEST_ON)}, got {self.best_on!r}")
        if self.learning_rate_schedule not in LEARNING_RATE_SCHEDULES:
            raise UserError(f"ppo 'learning_rate_schedule' must be one of {list(LEARNING_RATE_SCHEDULES)}, "
                            f"got {self.learning_rate_schedule!r}")
        if not 0 <= self.decay_start < 1:
            raise UserError(f"ppo 'decay_start' must be in [0, 1) (a fraction of num_timesteps), got {self.decay_start}")
        if not 0 <= self.final_learning_rate <= self.learning_rate:
            raise UserError(f"ppo 'final_learning_rate' must be between 0 and learning_rate ({self.learning_rate}), "
                            f"got {self.final_learning_rate}")
        if not 0 <= self.warmup < 1:
            raise UserError(f"ppo 'warmup' must be in [0, 1) (a fraction of num_timesteps), got {self.warmup}")
        if self.warmup and self.learning_rate_schedule == "adaptive_kl":
            raise UserError("ppo 'warmup' works with learning_rate_schedule 'none' or 'linear', not 'adaptive_kl'")
        if self.normalizer_warmup < 0:
            raise UserError(f"ppo 'normalizer_warmup' must be >= 0 (steps), got {self.normalizer_warmup}")
        if self.normalizer_warmup and not self.normalize_observations:
            raise UserError("ppo 'normalizer_warmup' needs normalize_observations = true")
        if not isinstance(self.init_from, str):
            raise UserError(f"ppo 'init_from' must be a run directory, a checkpoint or a shipped policy's env name, got {self.init_from!r}")
        if not self.desired_kl > 0:
            raise UserError(f"ppo 'desired_kl' must be > 0, got {self.desired_kl}")
        for name in ("init_noise_std", "max_noise_std"):
            value = getattr(self, name)
            if not (value == 0 or (math.isfinite(value) and value > _MIN_STD)):
                raise UserError(f"ppo '{name}' must be 0 (Brax's network unchanged) or a std > {_MIN_STD}, got {value}")
        if self.max_noise_std and self.init_noise_std >= self.max_noise_std:
            raise UserError(f"ppo 'init_noise_std' ({self.init_noise_std}) must be below 'max_noise_std' ({self.max_noise_std})")
        if not (self.discounting < 1 and self.gae_lambda <= 1):
            raise UserError(f"ppo 'discounting' must be < 1 and 'gae_lambda' <= 1, got {self.discounting}, {self.gae_lambda}")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Config":
        """The config as config.json records it (lists for the tuples). A config written before
        `max_noise_std` existed recorded an `init_noise_std` that Brax ignored: it is dropped."""
        data = dict(data)
        if "max_noise_std" not in data:
            data.pop("init_noise_std", None)
        return cls(**{**data, "policy_hidden": tuple(data["policy_hidden"]), "value_hidden": tuple(data["value_hidden"])})


def network_factory(config: Config, observation_size: int | Mapping | None = None, mirror=None) -> Callable:
    """Brax's PPO networks with our sizes; for a dict observation size (`privileged_observation`)
    the policy reads "state" and the critic "privileged_state". With `mirror` (an
    `envs.symmetry.Mirror`; needed when config.mirror_symmetric) the policy is mirror-equivariant
    (`_mirrored`); `init_noise_std` and `max_noise_std` transform its std (`_noise_std`). The
    parameters are those of the plain network, which checkpoints describe (`_brax_factory`)."""
    factory = _brax_factory(config, observation_size)
    if mirror is None and not (config.init_noise_std or config.max_noise_std):
        return factory

    def make(*args, **kwargs):
        networks = factory(*args, **kwargs)
        if mirror is not None:
            networks = _mirrored(networks, mirror)
        return _noise_std(networks, config.init_noise_std, config.max_noise_std)

    return make


def _brax_factory(config: Config, observation_size: int | Mapping | None) -> Callable:
    """Brax's plain PPO networks (a partial of `make_ppo_networks`, as its checkpoints record it)."""
    from brax.training.agents.ppo import networks as ppo_networks

    keys = {"policy_obs_key": "state", "value_obs_key": "privileged_state"} if isinstance(observation_size, Mapping) else {}
    return functools.partial(ppo_networks.make_ppo_networks, policy_hidden_layer_sizes=tuple(config.policy_hidden),
                             value_hidden_layer_sizes=tuple(config.value_hidden), **keys)


def _softplus_inverse(y: float) -> float:
    return math.log(math.expm1(y))


def _noise_std(networks, init_std: float, max_std: float):
    """`networks` whose policy's std output x (the second half: std = softplus(x) + 0.001) is shifted
    so that x = 0 gives `init_std`, then smoothly bounded, c − softplus(c − x), so that the std stays
    under `max_std`; the location (first half) is untouched. 0 leaves that step out."""
    import jax
    import jax.numpy as jnp

    if not (init_std or max_std):
        return networks
    shift = _softplus_inverse(init_std - _MIN_STD) if init_std else 0.0
    bound = _softplus_inverse(max_std - _MIN_STD) if max_std else None
    net = networks.policy_network

    def apply(processor_params, policy_params, obs):
        out = net.apply(processor_params, policy_params, obs)
        n = out.shape[-1] // 2
        x = out[..., n:] + shift
        if bound is not None:
            x = bound - jax.nn.softplus(bound - x)  # = x − softplus(x − c), without x's rounding at large x
        return jnp.concatenate([out[..., :n], x], axis=-1)

    return dataclasses.replace(networks, policy_network=dataclasses.replace(net, apply=apply))


def _mirrored(networks, mirror):
    """`networks` whose policy outputs ½ (f(o) + M_a f(M_o o)) for the plain network's output f and
    the reflections M_o of the observation and M_a of the action (on the tanh-normal's location, its
    scale permuted): the reflection of a situation gets the reflected action distribution."""
    import jax.numpy as jnp
    import numpy as np

    net = networks.policy_network
    n = mirror.action_perm.size
    out_perm = jnp.asarray(np.concatenate([mirror.action_perm, n + mirror.action_perm]))
    out_sign = jnp.asarray(np.concatenate([mirror.action_sign, np.ones(n, np.float32)]))

    def reflect(obs):
        if isinstance(obs, Mapping):  # the policy reads "state"
            return {**obs, "state": mirror.observation(obs["state"])}
        return mirror.observation(obs)

    def apply(processor_params, policy_params, obs):
        image = net.apply(processor_params, policy_params, reflect(obs))
        return 0.5 * (net.apply(processor_params, policy_params, obs) + image[..., out_perm] * out_sign)

    return dataclasses.replace(networks, policy_network=dataclasses.replace(net, apply=apply))


def env_network_factory(config: Config, env) -> Callable:
    """`network_factory` for env `env`: its observation size, and its `Mirror` where the policy is
    mirror-symmetric."""
    from marinejax.envs.symmetry import env_mirror

    return network_factory(config, env.observation_size, env_mirror(env) if config.mirror_symmetric else None)


def learning_rate_at(config: Config, env_steps):
    """The learning rate after `env_steps` env steps of a run (counted across resumes) for the
    "linear" schedule and a warmup; otherwise `learning_rate` ("adaptive_kl": its initial rate)."""
    import jax.numpy as jnp

    rate = jnp.asarray(config.learning_rate)
    if config.learning_rate_schedule == "linear":
        start = config.decay_start * config.num_timesteps
        fraction = jnp.clip((env_steps - start) / (config.num_timesteps - start), 0.0, 1.0)
        rate = config.learning_rate + fraction * (config.final_learning_rate - config.learning_rate)
    if config.warmup:
        rate = rate * jnp.clip(env_steps / (config.warmup * config.num_timesteps), 0.0, 1.0)
    return rate


class _ScheduledRate(float):
    """A learning rate that Brax's PPO takes in place of its float `learning_rate`: Brax hands it to
    optax's Adam, which calls a callable rate with its update count, and reports it as its
    `learning_rate` metric through `jnp.array`, which reads the float (the initial rate). Brax's
    train has no other way in for a schedule."""

    def __new__(cls, schedule: Callable, initial: float):
        rate = super().__new__(cls, initial)
        rate.schedule = schedule
        return rate

    def __call__(self, count):
        return self.schedule(count)


def brax_learning_rate(config: Config, steps_done: int = 0) -> float:
    """The `learning_rate` to give `brax.training.agents.ppo.train` for a call that starts after
    `steps_done` env steps of the run: the float, or the schedule (`learning_rate_at`)."""
    if config.learning_rate_schedule != "linear" and not config.warmup:
        return config.learning_rate
    # one training step: num_updates_per_batch × num_minibatches optimizer updates on
    # batch_size × unroll_length × num_minibatches env steps (Brax's `env_step_per_training_step`)
    updates_per_step = config.num_updates_per_batch * config.num_minibatches
    env_steps_per_step = config.batch_size * config.unroll_length * config.num_minibatches
    return _ScheduledRate(lambda count: learning_rate_at(config, steps_done + count / updates_per_step * env_steps_per_step),
                          float(learning_rate_at(config, steps_done)))


def run(env, config: Config, *, num_timesteps: int, seed: int, wrap_env_fn, progress_fn, save_fn, restore: Path | None,
        devices: int, checkpoint_dir: Path) -> None:
    """Brax PPO on `env`; `save_fn(step, params)` after every evaluation (step counted from this call's start)."""
    from brax.training.agents.ppo import train as ppo_train

    from marinejax.envs.wrappers import FixedEpisodes

    # a resumed run continues its schedule where it stopped (Brax starts a new optimizer state)
    steps_done = config.num_timesteps - num_timesteps
    rate = brax_learning_rate(config, steps_done)

    def progress(step, metrics):
        # Brax reports the float of a scheduled rate (its start); report the rate at this step
        if callable(rate) and "training/learning_rate" in metrics:
            metrics = {**metrics, "training/learning_rate": float(learning_rate_at(config, steps_done + step))}
        progress_fn(step, metrics)

    ppo_train.train(
        environment=env,
        eval_env=FixedEpisodes(env, seed=0) if config.fixed_eval_episodes else None,
        num_timesteps=num_timesteps,
        episode_length=env.config.episode_length,
        wrap_env_fn=wrap_env_fn,
        num_envs=config.num_envs,
        unroll_length=config.unroll_length,
        batch_size=config.batch_size,
        num_minibatches=config.num_minibatches,
        num_updates_per_batch=config.num_updates_per_batch,
        learning_rate=rate,
        learning_rate_schedule="ADAPTIVE_KL" if config.learning_rate_schedule == "adaptive_kl" else "NONE",
        desired_kl=config.desired_kl,
        entropy_cost=config.entropy_cost,
        discounting=config.discounting,
        gae_lambda=config.gae_lambda,
        clipping_epsilon=config.clipping_epsilon,
        reward_scaling=config.reward_scaling,
        max_grad_norm=config.max_grad_norm,
        normalize_observations=config.normalize_observations,
        network_factory=env_network_factory(config, env),
        num_evals=config.num_evals,
        num_eval_envs=config.num_eval_envs,
        deterministic_eval=True,
        seed=seed,
        restore_checkpoint_path=str(restore) if restore else None,
        restore_params=initial_params(env, config, seed) if restore is None else None,
        progress_fn=progress,
        policy_params_fn=lambda step, make_policy, params: save_fn(step, params) if step > 0 else None,
        max_devices_per_host=devices,
    )


def warmup_observations(env, config: Config, seed: int):
    """The observations (steps, num_envs, ...) of `config.normalizer_warmup` steps of `num_envs` envs
    of `env`, reset with keys from `seed`, under actions drawn uniformly in [−1, 1]."""
    import jax

    key_reset, key_actions = jax.random.split(jax.random.fold_in(jax.random.PRNGKey(seed), 0x6e6f726d))

    def rollout(key_reset, key_actions):
        state = jax.vmap(env.reset)(jax.random.split(key_reset, config.num_envs))

        def step(state, key):
            action = jax.random.uniform(key, (config.num_envs, env.action_size), minval=-1.0, maxval=1.0)
            state = jax.vmap(env.step)(state, action)
            return state, state.obs

        return jax.lax.scan(step, state, jax.random.split(key_actions, config.normalizer_warmup))[1]

    return jax.jit(rollout)(key_reset, key_actions)


def warmup_normalizer(env, config: Config, seed: int):
    """Brax's observation normalizer state (running mean and std) of `warmup_observations`."""
    import jax
    import jax.numpy as jnp
    from brax.training.acme import running_statistics

    observations = warmup_observations(env, config, seed)
    shapes = jax.tree_util.tree_map(lambda x: jax.ShapeDtypeStruct(x.shape[-1:], jnp.float32), observations)
    return running_statistics.update(running_statistics.init_state(shapes), observations)


def initial_params(env, config: Config, seed: int):
    """(normalizer, policy, value) to start Brax's PPO from, or None for Brax's own start: the
    checkpoint of `config.init_from` (`from_checkpoint`), or Brax's own initial networks for `seed`
    (the keys its `train` derives) with the normalizer of `warmup_normalizer`."""
    import jax
    from brax.training.acme import running_statistics

    if config.init_from:
        return from_checkpoint(env, config, seed)
    if not config.normalizer_warmup:
        return None
    normalizer = warmup_normalizer(env, config, seed)
    key_policy, key_value = jax.random.split(jax.random.split(jax.random.PRNGKey(seed))[0])
    shapes = jax.tree_util.tree_map(lambda x: x.shape, normalizer.mean)
    networks = env_network_factory(config, env)(shapes, env.action_size, preprocess_observations_fn=running_statistics.normalize)
    return normalizer, networks.policy_network.init(key_policy), networks.value_network.init(key_value)


def from_checkpoint(env, config: Config, seed: int):
    """The params (normalizer, policy, value) of `config.init_from`'s best checkpoint, checked against
    `env` and `config`: a PPO run with the same action size, network sizes and mirror symmetry, and
    observation fields that this env's include (UserError naming the difference); widened to this
    env's observation by `widen_inputs` where it has more fields."""
    from marinejax.train.checkpoints import load_params  # the checkpoint layer reads the algorithms' configs

    source, source_env, params, ckpt = load_params(config.init_from)
    what = f"ppo 'init_from' {config.init_from!r} ({ckpt})"
    if source.algorithm != "ppo":
        raise UserError(f"ppo 'init_from' {config.init_from!r} is a {source.algorithm.upper()} run; a PPO run starts from a PPO checkpoint")
    mine = (tuple(config.policy_hidden), tuple(config.value_hidden), config.mirror_symmetric)
    theirs = (tuple(source.agent.policy_hidden), tuple(source.agent.value_hidden), source.agent.mirror_symmetric)
    for name, a, b in zip(("policy_hidden", "value_hidden", "mirror_symmetric"), mine, theirs):
        if a != b:
            raise UserError(f"{what} has {name} {b}, this run {a} (--ppo init_from= trains from scratch)")
    actions = None if env.action_size == source_env.action_size else action_map(source_env, env, what)
    rows = input_rows(source_env, env, what, actions)
    if actions is not None:
        params = map_actions(params, actions)
    new = [] if rows is None else [name for name, s in env.observation_fields().items() if (rows[s] < 0).all()]
    if not new:
        if config.normalizer_warmup:
            raise UserError(f"ppo 'normalizer_warmup' {config.normalizer_warmup} has nothing to warm: 'init_from' "
                            f"{config.init_from!r} ({ckpt}) has this env's observation fields and its normalizer (set it to 0)")
        return params if rows is None else widen_inputs(params, rows, None, input_gains(env, actions))
    if not config.normalizer_warmup:
        raise UserError(f"{what} lacks this env's observation fields {new}: set --ppo normalizer_warmup=N, the "
                        "random-action steps whose observations give their normalizer statistics")
    return widen_inputs(params, rows, warmup_normalizer(env, config, seed), input_gains(env, actions))


@dataclasses.dataclass(frozen=True, eq=False)
class ActionMap:
    """This env's action from a source policy's: action = sign * source_action[take] (shapes (A,)),
    each source component copied to `count[i]` components (shape (A_source,))."""

    take: Any
    sign: Any
    count: Any


def action_map(source_env, env, what: str) -> ActionMap:
    """How `env`'s vehicle carries out the actions of `source_env`'s when the two steer alike with
    other actuators: torpedoes whose fins are laid out differently (`actuators.fin.steering_mix`:
    the REMUS 100's rudder and stern-plane pair, the four-fin variant's independent fins), each of
    this env's actuators following one source command, signed. Else a UserError naming the sizes."""
    import numpy as np

    from marinejax.actuators.fin import steering_mix

    def mix(e):
        if e.config.action_mode != "thrusters":
            return None
        try:
            return steering_mix(e.plant.sys.actuators)
        except UserError:  # not a torpedo
            return None

    theirs, mine = mix(source_env), mix(env)
    problem = f"{what} has action size {source_env.action_size}, this run {env.action_size}"
    if theirs is None or mine is None:
        raise UserError(f"{problem} (--ppo init_from= trains from scratch)")
    matrix = mine @ np.linalg.pinv(theirs)  # this env's action per unit source action
    take = np.argmax(np.abs(matrix), axis=1)
    sign = np.sign(matrix[np.arange(len(take)), take]).astype(np.float32)
    exact = np.zeros_like(matrix)
    exact[np.arange(len(take)), take] = sign
    if not np.allclose(matrix, exact, atol=1e-6) or set(take) != set(range(source_env.action_size)):
        raise UserError(f"{problem}, and its actuators map to this vehicle's only by mixing commands "
                        "(--ppo init_from= trains from scratch)")
    return ActionMap(take=take, sign=sign, count=np.bincount(take, minlength=source_env.action_size))


def map_actions(params, actions: ActionMap):
    """`params` (normalizer, policy, value) whose policy outputs `actions`' actions: the last layer's
    location columns taken and signed by the map (tanh is odd, so each action is exactly the mapped
    source action), its std columns taken."""
    import jax.numpy as jnp
    import numpy as np

    normalizer, policy, value = params
    layers = policy["params"]
    last = max((name for name in layers if name.startswith("hidden_")), key=lambda name: int(name.split("_")[1]))
    size = np.asarray(layers[last]["bias"]).shape[-1] // 2
    columns = np.concatenate([actions.take, size + actions.take])
    signs = np.concatenate([actions.sign, np.ones_like(actions.sign)])
    mapped = {k: jnp.asarray(np.asarray(v)[..., columns] * signs, np.asarray(v).dtype) for k, v in layers[last].items()}
    return normalizer, {**policy, "params": {**layers, last: mapped}}, value


def input_gains(env, actions: ActionMap | None):
    """Per component of `env`'s observation, the factor its source component is read with under
    `actions`: sign / count on the fields that hold one entry per actuator (`symmetry.FIELD_SIGNS`
    "action"), whose source component is then the mean of the signed components copying it; 1
    elsewhere (None without a map)."""
    import numpy as np

    from marinejax.envs.symmetry import FIELD_SIGNS

    if actions is None:
        return None
    gains = np.ones(env.observation_size, np.float32)
    for name, s in env.observation_fields().items():
        if FIELD_SIGNS.get(name) == "action":
            gains[s] = actions.sign / actions.count[actions.take]
    return gains


def input_rows(source_env, env, what: str, actions: ActionMap | None = None):
    """Per component of `env`'s observation, the component of `source_env`'s observation holding the
    same field (−1 for a field the source lacks), or None where the two layouts are the same. Every
    source field must be in `env` with its size, else a UserError naming them; with `actions`, the
    fields with one entry per actuator (`symmetry.FIELD_SIGNS` "action") take the mapped source
    actuator's."""
    import numpy as np

    from marinejax.envs.symmetry import FIELD_SIGNS

    sizes = (source_env.observation_size, env.observation_size)
    if any(isinstance(size, dict) for size in sizes):  # a privileged observation: its own layout, not mapped by field
        if sizes[0] != sizes[1]:
            raise UserError(f"{what} has observation size {sizes[0]}, this run {sizes[1]} (--ppo init_from= trains from scratch)")
        return None
    theirs, mine = source_env.observation_fields(), env.observation_fields()
    missing = [name for name in theirs if name not in mine]
    per_actuator = {name for name in theirs if actions is not None and FIELD_SIGNS.get(name) == "action"}
    resized = [name for name, s in theirs.items()
               if name in mine and name not in per_actuator and s.stop - s.start != mine[name].stop - mine[name].start]
    if missing or resized:
        raise UserError(f"{what} has observation size {sizes[0]}, this run {sizes[1]}: this env lacks its fields {missing}"
                        f"{f' and sizes differently {resized}' if resized else ''} (--ppo init_from= trains from scratch)")
    rows = np.full(env.observation_size, -1)
    for name, s in theirs.items():
        rows[mine[name]] = s.start + actions.take if name in per_actuator else np.arange(s.start, s.stop)
    return None if np.array_equal(rows, np.arange(sizes[0])) else rows


def widen_inputs(params, rows, warm, gains=None):
    """`params` (normalizer, policy, value) of a source observation laid out again by `rows`
    (`input_rows`): each component's normalizer statistics and first-layer weights from the source
    component it holds, and for the fields the source lacks (rows −1) first-layer weights 0, so that
    the networks compute the source's functions, and the mean and std of the warm-up normalizer
    `warm` (their summed variance scaled to the source's count, as if the source had seen them; None
    where no field is new). `gains` (`input_gains`): per component, the factor the source component
    is read with; its sign also signs the normalizer's mean, so that each normalized source
    component is the gain-weighted sum of the normalized components holding it."""
    import jax.numpy as jnp
    import numpy as np

    normalizer, policy, value = params
    new = rows < 0
    take = np.maximum(rows, 0)
    gains = np.ones(len(rows), np.float32) if gains is None else np.asarray(gains)
    count = lambda state: float(int(state.count.hi) * 2**32 + int(state.count.lo))  # noqa: E731  Brax's UInt64 count

    def merge(source, fresh, factor=1.0):
        source = np.asarray(source)
        fresh = source[take] if fresh is None else np.asarray(fresh)
        return jnp.asarray(np.where(new, fresh, source[take] * factor), source.dtype)

    fresh_variance = None if warm is None else np.asarray(warm.summed_variance) * count(normalizer) / count(warm)
    normalizer = normalizer.replace(mean=merge(normalizer.mean, None if warm is None else warm.mean, np.sign(gains)),
                                    std=merge(normalizer.std, None if warm is None else warm.std),
                                    summed_variance=merge(normalizer.summed_variance, fresh_variance))

    def first_layer(network):
        layers = network["params"]
        if "hidden_0" not in layers:
            raise ValueError(f"a Brax MLP's first layer is 'hidden_0'; these params have {sorted(layers)}")
        kernel = np.asarray(layers["hidden_0"]["kernel"])
        widened = jnp.asarray(np.where(new[:, None], 0.0, kernel[take] * gains[:, None]), kernel.dtype)
        return {**network, "params": {**layers, "hidden_0": {**layers["hidden_0"], "kernel": widened}}}

    return normalizer, first_layer(policy), first_layer(value)


def save(path: Path, step: int, params, env, config: Config) -> None:
    """A Brax PPO checkpoint `path/<step:012d>` (normalizer, policy, value params + network config)."""
    from brax.training.agents.ppo import checkpoint

    save_checkpoint(checkpoint, _brax_factory(config, env.observation_size), path, step, params, env, config.normalize_observations,
                    NETWORK_CONFIG)


def load(path: Path):
    """The params (normalizer, policy, value) of a checkpoint directory."""
    from brax.training.agents.ppo import checkpoint as ppo_checkpoint

    return ppo_checkpoint.load(path)


def policy(config: Config, env, params) -> Callable:
    """The deterministic policy (observation → action) of `params`."""
    from brax.training.agents.ppo import networks

    return deterministic_policy(networks, env_network_factory(config, env), env, params, config.normalize_observations)
