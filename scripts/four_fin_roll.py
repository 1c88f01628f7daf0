"""Whether a four-fin autopilot policy uses its roll authority (developer tool, not installed).

    python scripts/four_fin_roll.py [RUN_OR_SHIPPED_NAME]   (default: Remus100FourFin-Autopilot; e.g. Remus100FourFin-CircleFollowing)

Flies the policy, then its recipe's starting policy (a REMUS 100 policy mapped onto the four fins,
which never commands roll), then that REMUS 100 policy on its own vehicle, each on its env's 64
evaluation episodes (seed 12345), and prints the RMS of the normalised fin commands split into
their roll part (all four fins alike: all at +δ roll the vehicle port side down), the yaw pair
((top − bottom) / 2), the pitch pair ((starboard − port) / 2) and the opposed part that makes no
moment, with the roll angle (mean and 95th percentile of |roll|, degrees, from the observed world
up in the body frame) over every step.
"""

from __future__ import annotations

import sys

import jax
import numpy as np

from marinejax.control import policy_controller, rollout
from marinejax.train import ppo
from marinejax.train.checkpoints import load_policy
from marinejax.train.hyperparams import tuned_config


def measure(env, policy, label: str) -> None:
    keys = jax.random.split(jax.random.PRNGKey(12345), 64)
    _, obs = rollout(env, policy_controller(policy), keys, record=lambda s: s.obs)
    a = np.asarray(jax.vmap(jax.vmap(policy))(obs))  # the command each step's observation gets
    o = np.asarray(obs)
    roll = np.abs(np.degrees(np.arctan2(o[..., 5], o[..., 6])))  # observation [4:7]: world up, body frame FLU
    line = f"{label}: roll angle mean {roll.mean():.3f}°, 95th percentile {np.percentile(roll, 95):.3f}°"
    if a.shape[-1] == 5:  # the four fins, then the propeller
        rms = lambda x: float(np.sqrt(np.mean(x**2)))  # noqa: E731
        line += (f"; RMS fin command: roll {rms(a[..., :4].mean(-1)):.4f}, yaw pair {rms((a[..., 0] - a[..., 1]) / 2):.4f}, "
                 f"pitch pair {rms((a[..., 3] - a[..., 2]) / 2):.4f}, opposed {rms((a[..., 0] + a[..., 1] - a[..., 2] - a[..., 3]) / 4):.4f}")
    print(line, flush=True)


def main(source: str = "Remus100FourFin-Autopilot") -> None:
    config, env, policy, ckpt = load_policy(source)
    measure(env, jax.jit(policy), f"{source} ({ckpt.name})")
    start = tuned_config(config.env).ppo
    if start.init_from:
        params = ppo.initial_params(env, start, seed=0)
        measure(env, jax.jit(ppo.policy(start, env, params)), f"its recipe's start ({start.init_from} mapped)")
        _, remus_env, remus_policy, _ = load_policy(start.init_from)
        measure(remus_env, jax.jit(remus_policy), f"{start.init_from} on its own vehicle")


if __name__ == "__main__":
    main(*sys.argv[1:2])
