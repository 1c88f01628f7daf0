"""Developer tool: what a recipe that starts from another policy (`--ppo init_from`) starts with: the
source policy laid out for the env (new observation fields at weight 0, another torpedo's fins
following their pair: `ppo.initial_params`), evaluated before any training on the 64 episodes that
`marinejax eval` uses (seed 12345).

    python scripts/evaluate_start.py Remus100FourFin-Autopilot Remus100FourFin-Docking
"""

from __future__ import annotations

import argparse
import json

import marinejax as mj
from marinejax.statistics import rollout_policy, summarize
from marinejax.train import ppo
from marinejax.train.hyperparams import tuned_config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("envs", nargs="+", help="registered env names whose PPO recipe has init_from")
    parser.add_argument("--episodes", type=int, default=64)
    parser.add_argument("--seed", type=int, default=12345)
    args = parser.parse_args()
    for name in args.envs:
        recipe = tuned_config(name)
        if not recipe.ppo.init_from:
            raise SystemExit(f"{name}: its recipe trains from scratch (no init_from)")
        env = mj.make(name, **recipe.env_overrides)
        params = ppo.initial_params(env, recipe.ppo, seed=0)
        stats = summarize(env, rollout_policy(env, ppo.policy(recipe.ppo, env, params), args.episodes, args.seed))
        print(name, "from", recipe.ppo.init_from, json.dumps({k: v for k, v in stats.items() if isinstance(v, (int, float))}), flush=True)


if __name__ == "__main__":
    main()
