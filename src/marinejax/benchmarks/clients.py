"""Steps per second of a marinejax env through the RL libraries' own paths, beside the jitted batch.

    marinejax bench clients [--env NAME] [--envs-per-client 8] [--steps 2000] [--ppo-steps 16384]

Measured in one run on one machine (random actions unless PPO; compilation excluded by a warm-up):
  * Gymnasium single env (`gymnasium.make`), a Python loop: one jitted call per step;
  * Gymnasium vector env (`gymnasium.make_vec`, all envs in one jitted call);
  * SB3 `DummyVecEnv` over single envs (what `make_vec_env` builds) and the shipped
    `marinejax.envs.sb3.MarineJaxSB3VecEnv`, stepping, and SB3 PPO `learn` on each;
  * TorchRL `GymEnv` rollout and a TorchRL collector over `GymWrapper(make_vec(...))`;
  * the native path: the Brax env vmapped and jitted over 4096 envs, 20 steps per call.
SB3 and TorchRL rows need the optional extras (pip install "marinejax[sb3,torchrl]"); rows whose
library is missing are reported as such.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from marinejax.benchmarks.common import fmt_rate, positive
from marinejax.console import make_console
from marinejax.machine import machine_info


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="marinejax bench clients", description=__doc__.split("\n")[0])
    p.add_argument("--env", default="BlueROV2Heavy-CircleTracking", help="env name (default BlueROV2Heavy-CircleTracking)")
    p.add_argument("--envs-per-client", type=positive(int), default=8, help="envs of the vectorized clients (default 8)")
    p.add_argument("--steps", type=positive(int), default=2000, help="env steps timed per stepping row (default 2000)")
    p.add_argument("--ppo-steps", type=positive(int), default=16384, help="env steps of each SB3 PPO learn row (default 16384)")
    p.add_argument("--out", type=Path, help="also write the results as JSON here")
    return p


def _rate(run: Callable[[], int], warmup: Callable[[], Any] | None = None) -> float:
    """Env steps per second of `run()` (which returns the env steps it took), after `warmup()`."""
    if warmup is not None:
        warmup()
    start = time.perf_counter()
    steps = run()
    return steps / (time.perf_counter() - start)


def _gym_single(env_id: str, steps: int) -> float:
    import gymnasium

    env = gymnasium.make(env_id)
    rng = np.random.default_rng(0)

    def run(n=steps):
        env.reset(seed=0)
        for _ in range(n):
            _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
            if term or trunc:
                env.reset()
        return n

    return _rate(run, lambda: run(20))


def _stepper(reset: Callable, step: Callable, shape: tuple[int, ...], n_envs: int, steps: int) -> float:
    rng = np.random.default_rng(0)

    def run(n=steps):
        reset()
        for _ in range(max(1, n // n_envs)):
            step(rng.uniform(-1, 1, shape).astype(np.float32))
        return max(1, n // n_envs) * n_envs

    return _rate(run, lambda: run(2 * n_envs))


def _sb3_learn(venv, steps: int) -> float:
    from stable_baselines3 import PPO

    model = PPO("MlpPolicy", venv, n_steps=256, batch_size=256, n_epochs=4, seed=0, device="cpu", verbose=0)
    model.learn(total_timesteps=venv.num_envs * 256)  # warm-up: compilation and first update
    before = model.num_timesteps
    start = time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    return (model.num_timesteps - before) / (time.perf_counter() - start)


def _native(env_name: str) -> float:
    import jax

    from marinejax.envs import make

    env = make(env_name)
    batch, length = 4096, 20
    keys = jax.random.split(jax.random.PRNGKey(0), batch)
    actions = jax.random.uniform(jax.random.PRNGKey(1), (length, batch, env.action_size), minval=-1, maxval=1)

    @jax.jit
    def unroll(state):
        def body(s, a):
            return jax.vmap(env.step)(s, a), None

        return jax.lax.scan(body, state, actions)[0]

    state = jax.jit(jax.vmap(env.reset))(keys)
    jax.block_until_ready(unroll(state))
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        jax.block_until_ready(unroll(state))
        best = min(best, time.perf_counter() - start)
    return batch * length / best


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    import gymnasium

    import marinejax
    from marinejax.envs.gym_adapter import gymnasium_id

    console = make_console()
    if args.env not in marinejax.list_envs():
        print(f"marinejax bench clients: error: unknown env {args.env!r}; valid: {marinejax.list_envs()}", file=sys.stderr)
        return 2
    env_id, n = gymnasium_id(args.env), args.envs_per_client
    info = machine_info()
    console.print(f"marinejax bench clients: {args.env}, {n} envs per vectorized client, {args.steps} env steps per stepping row")
    console.print(f"machine: {info['cpu']} | {info['cpu_count']} cores | jax {info['jax']} {info['backend']}")
    rows: list[tuple[str, str, float | None, str]] = []

    def add(client: str, path: str, fn: Callable[[], float]) -> None:
        try:
            rate = fn()
            rows.append((client, path, rate, ""))
        except ImportError as err:
            rows.append((client, path, None, f"not installed ({err.name})"))
        console.print(f"  {client} | {path}: {fmt_rate(rows[-1][2]) if rows[-1][2] else rows[-1][3]}", markup=False)

    add("Gymnasium", "gymnasium.make, Python loop", lambda: _gym_single(env_id, args.steps))

    def gym_vec():
        envs = gymnasium.make_vec(env_id, num_envs=n)
        return _stepper(lambda: envs.reset(seed=0), envs.step, envs.action_space.shape, n, args.steps)

    add("Gymnasium", f"gymnasium.make_vec, {n} envs in one jitted call", gym_vec)

    def sb3_dummy(learn=False):
        from stable_baselines3.common.env_util import make_vec_env

        venv = make_vec_env(env_id, n_envs=n, seed=0)
        if learn:
            return _sb3_learn(venv, args.ppo_steps)
        return _stepper(venv.reset, venv.step, (n, *venv.action_space.shape), n, args.steps)

    def sb3_marinejax(learn=False):
        from marinejax.envs.sb3 import MarineJaxSB3VecEnv

        venv = MarineJaxSB3VecEnv(args.env, num_envs=n)
        if learn:
            return _sb3_learn(venv, args.ppo_steps)
        return _stepper(venv.reset, venv.step, (n, *venv.action_space.shape), n, args.steps)

    add("SB3", f"make_vec_env (DummyVecEnv), {n} envs, stepping", sb3_dummy)
    add("SB3", f"MarineJaxSB3VecEnv, {n} envs, stepping", sb3_marinejax)
    add("SB3", f"PPO learn on DummyVecEnv, {n} envs", lambda: sb3_dummy(learn=True))
    add("SB3", f"PPO learn on MarineJaxSB3VecEnv, {n} envs", lambda: sb3_marinejax(learn=True))

    def torchrl_single():
        from torchrl.envs import GymEnv

        env = GymEnv(env_id)
        return _rate(lambda: env.rollout(args.steps, break_when_any_done=False).numel(), lambda: env.rollout(20))

    def torchrl_collector():
        from torchrl.collectors import Collector
        from torchrl.envs import GymWrapper

        env = GymWrapper(gymnasium.make_vec(env_id, num_envs=n, autoreset_mode="same_step"))
        frames = max(n, args.steps // n * n)
        collector = Collector(env, policy=None, frames_per_batch=frames, total_frames=3 * frames)
        it = iter(collector)
        next(it)  # warm-up
        start = time.perf_counter()
        got = sum(next(it).numel() for _ in range(2))
        rate = got / (time.perf_counter() - start)
        collector.shutdown()
        return rate

    add("TorchRL", "GymEnv rollout (single env)", torchrl_single)
    add("TorchRL", f"Collector over GymWrapper(make_vec), {n} envs", torchrl_collector)
    add("marinejax", "Brax env, vmap + jit, 4096 envs x 20 steps per call", lambda: _native(args.env))

    console.print()
    for client, path, rate, note in rows:
        console.print(f"{client:10s} {path:58s} {fmt_rate(rate) + ' env steps/s' if rate else note}", markup=False)
    if args.out:
        args.out.write_text(json.dumps({"env": args.env, "machine": info, "envs_per_client": n, "rows": [
            {"client": c, "path": p, "env_steps_per_s": r, "note": note} for c, p, r, note in rows]}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
