"""Developer tool: record every registered env's outputs and compare two recordings (redesigns must
keep env behaviour; see docs/architecture.md).

    python scripts/compare_envs.py record before.npz            # on the old commit
    python scripts/compare_envs.py record after.npz             # on the new one
    python scripts/compare_envs.py compare before.npz after.npz # largest |difference| per env and field

A recording holds, per env, 8 envs reset from fixed keys and stepped 100 times with uniform random
actions in [-1, 1]: observation, reward, done and the plant state (qpos, qvel, actuator state) after
every step. Two extra variants per vehicle cover sensor mode (with randomization, latency and
privileged observation) and the disturbed station keeping in wrench mode.
"""

from __future__ import annotations

import argparse
import sys

import jax
import numpy as np

import marinejax as mj

BATCH, STEPS = 8, 100
VARIANTS = {
    "sensors": {"observation_mode": "sensors", "randomization.enabled": True, "privileged_observation": True},
    "wrench": {"action_mode": "wrench"},
}


def cases() -> list[tuple[str, str, dict]]:
    out = [(name, name, {}) for name in mj.list_envs()]
    for name in mj.list_envs():
        if name.endswith("-StationKeepingDisturbed"):
            out += [(f"{name}+{v}", name, o) for v, o in VARIANTS.items()]
    return out


def record_one(name: str, overrides: dict) -> dict[str, np.ndarray]:
    env = mj.make(name, **overrides)
    keys = jax.random.split(jax.random.PRNGKey(0), BATCH)
    actions = jax.random.uniform(jax.random.PRNGKey(1), (STEPS, BATCH, env.action_size), minval=-1.0, maxval=1.0)

    @jax.jit
    def run(keys, actions):
        state = jax.vmap(env.reset)(keys)

        def body(state, action):
            state = jax.vmap(env.step)(state, action)
            ps = state.pipeline_state.physics
            leaves = {"obs": state.obs, "reward": state.reward, "done": state.done,
                      "qpos": ps.data.qpos, "qvel": ps.data.qvel, "actuators": jax.tree.leaves(ps)[-1]}
            return state, leaves

        return jax.lax.scan(body, state, actions)[1]

    out = run(keys, actions)
    flat = {}
    for k, v in out.items():
        if isinstance(v, dict):
            flat.update({f"{k}.{kk}": np.asarray(vv) for kk, vv in v.items()})
        else:
            flat[k] = np.asarray(v)
    return flat


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("out")
    r.add_argument("--envs", default="", help="comma-separated case names (default: all)")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    args = p.parse_args(argv)
    if args.cmd == "record":
        wanted = set(filter(None, args.envs.split(",")))
        arrays = {}
        for case, name, overrides in cases():
            if wanted and case not in wanted:
                continue
            for k, v in record_one(name, overrides).items():
                arrays[f"{case}/{k}"] = v
            print(case, flush=True)
        np.savez_compressed(args.out, **arrays)
        return 0
    a, b = np.load(args.a), np.load(args.b)
    worst = 0.0
    bad = False
    for case in sorted({k.split("/")[0] for k in a.files}):
        diffs = {}
        for k in sorted(f for f in a.files if f.startswith(case + "/")):
            if k not in b.files or a[k].shape != b[k].shape:
                print(f"{case}: {k.split('/')[1]} missing or reshaped")
                bad = True
                continue
            d = np.abs(a[k].astype(np.float64) - b[k].astype(np.float64))
            same_nan = np.isnan(a[k]) & np.isnan(b[k])
            diffs[k.split("/")[1]] = float(np.max(np.where(same_nan, 0.0, d), initial=0.0))
        m = max(diffs.values(), default=0.0)
        worst = max(worst, m)
        detail = "identical" if m == 0 else ", ".join(f"{k} {v:.3g}" for k, v in diffs.items() if v > 0)
        print(f"{case:55s} max |diff| {m:.3g}  ({detail})")
    print(f"largest difference over all envs: {worst:.3g}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
