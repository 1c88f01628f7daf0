"""Developer tool: PPO learning a residual on a classical controller. The policy's action (in
[−1, 1] per actuator) is scaled by `--scale` and added to the controller's (`marinejax.controllers`,
tuned as `marinejax eval --controller` tunes it), the sum clipped to [−1, 1]; the controller's state
(its integrals) rides in the env state. Trains the env's recipe with the given PPO settings, then
evaluates the best and the latest checkpoint with the controller, and the controller alone, on the
64 episodes `marinejax eval` uses (seed 12345).

    python scripts/residual_experiment.py Remus100-TerrainFollowing autopilot --seed 0 --run-dir runs/res \
        --ppo num_timesteps=10000000 --ppo num_evals=11 --ppo learning_rate_schedule=linear
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax.numpy as jnp
from brax.envs.base import Wrapper

from marinejax.config import parse_key_values
from marinejax.control import Controller
from marinejax.controllers import make_controller
from marinejax.statistics import rollout_controller, summarize
from marinejax.train import hyperparams, runner
from marinejax.train.checkpoints import load_policy


def _sum(base, residual, scale: float):
    """The controller's action plus `scale` × the residual, within the action space."""
    return jnp.clip(base + scale * residual, -1.0, 1.0)


class Residual(Wrapper):
    """The env with `controller`'s action plus `scale` × the given action as its action."""

    def __init__(self, env, controller: Controller, scale: float):
        super().__init__(env)
        self.controller, self.scale = controller, scale

    def reset(self, rng):
        state = self.env.reset(rng)
        state.info["residual_carry"] = self.controller.init(rng)
        return state

    def step(self, state, action):
        base, carry = self.controller.act(state.info["residual_carry"], state.obs, state.info)
        state = self.env.step(state, _sum(base, action, self.scale))
        state.info["residual_carry"] = carry
        return state


def with_residual(controller: Controller, policy, scale: float) -> Controller:
    def act(carry, obs, info):
        base, carry = controller.act(carry, obs, info)
        return _sum(base, policy(obs), scale), carry

    return Controller(init=controller.init, act=act)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("env")
    parser.add_argument("controller")
    parser.add_argument("--scale", type=float, default=0.3, help="the policy's share of the action range")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--run-dir", type=Path, required=True)
    parser.add_argument("--ppo", action="append", default=[], metavar="K=V")
    args = parser.parse_args()
    config = hyperparams.with_overrides(hyperparams.tuned_config(args.env), ppo={**parse_key_values(args.ppo, "--ppo"), "seed": args.seed})
    env = hyperparams.build_env(config)
    controller, description = make_controller(args.controller, env, progress=print)
    print("controller", json.dumps(description["config"]), flush=True)
    runner.build_env = lambda _: Residual(env, controller, args.scale)  # the runner trains on the wrapped env
    runner.train(config, args.run_dir, on_eval=lambda r: print(f"step {r['step']} {r['elapsed']:.0f} s: training "
                                                                f"evaluation {r.get('eval/episode_window_error')}", flush=True))
    keep = ("position_error_mean_m", "position_error_median_m", "position_error_p95_m", "success_rate", "heading_error_mean_deg",
            "speed_error_mean")
    for which in ("best", "latest"):
        _, _, policy, ckpt = load_policy(args.run_dir, which=which)
        result = summarize(env, rollout_controller(env, with_residual(controller, policy, args.scale), 64, 12345))
        print(which, ckpt.name, json.dumps({k: result.get(k) for k in keep}), flush=True)
    result = summarize(env, rollout_controller(env, controller, 64, 12345))
    print(args.controller, "alone", json.dumps({k: result.get(k) for k in keep}), flush=True)


if __name__ == "__main__":
    main()
