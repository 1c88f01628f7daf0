"""Env speed of two checkouts in one table: the same timing code (this script) runs each checkout's
package alternately (rounds of before, after) on the same machine in one session, so both see the
same load and the same harness; per env and batch the median env steps/s of each and their ratio.

    python scripts/bench_before_after.py BEFORE_SRC AFTER_SRC [--envs A,B] [--batch-sizes 256,1024]
                                         [--rounds 5] [--out FILE.json]

BEFORE_SRC and AFTER_SRC are the `src` folders of two checkouts (e.g. a `git worktree` of the commit
before a redesign, and this one). Timed per env and batch by `benchmarks.common.time_calls` (the
best of interleaved calls after compilation; the same code at both ends of the redesign compared here): `env_step` a jitted `lax.scan` of 20 vmapped `env.step` under uniform random actions
in [−1, 1] drawn beforehand, `plant_step` the same of `env.plant.step` alone (actuators and physics). It
uses only what both ends of a redesign have (`marinejax.make`, `reset`, `step`, `plant.step`), not
`marinejax bench envs`, whose own harness may differ between the two.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

STEPS = 20


def measure(envs: list[str], batches: list[int]) -> list[dict]:
    """Run in the checkout's interpreter (PYTHONPATH): env steps/s of env.step and plant.step."""
    import jax

    import marinejax
    from marinejax.benchmarks.common import time_calls

    rows = []
    for name in envs:
        env = marinejax.make(name)
        for batch in batches:
            keys = jax.random.split(jax.random.PRNGKey(0), batch)
            state = jax.jit(jax.vmap(env.reset))(keys)
            actions = jax.random.uniform(jax.random.PRNGKey(1), (STEPS, batch, env.action_size), minval=-1.0, maxval=1.0)

            @jax.jit
            def full(s, a):
                return jax.lax.scan(lambda s, a: (jax.vmap(env.step)(s, a), None), s, a)[0].obs

            @jax.jit
            def plant(s, a):
                def body(ps, a):
                    return jax.vmap(env.plant.step)(s.info["params"], ps, a, keys)[0], None

                return jax.lax.scan(body, s.pipeline_state, a)[0].physics.data.qpos

            timed = time_calls({"env_step": lambda: full(state, actions), "plant_step": lambda: plant(state, actions)})
            row = {"env": name, "batch": batch, **{part: batch * STEPS / t["seconds"] for part, t in timed.items()}}
            rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before", type=Path, nargs="?", help="the src folder of the checkout before")
    p.add_argument("after", type=Path, nargs="?", help="the src folder of the checkout after")
    p.add_argument("--envs", default="BlueROV2Heavy-StationKeeping,BlueROV2Heavy-CircleTracking,BlueROV2-StationKeeping")
    p.add_argument("--batch-sizes", default="256,1024")
    p.add_argument("--rounds", type=int, default=5, help="alternations of before and after (default 5)")
    p.add_argument("--out", type=Path, help="also write every measurement and the table as JSON")
    p.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)  # the child process's mode
    args = p.parse_args(argv)
    envs, batches = args.envs.split(","), [int(b) for b in args.batch_sizes.split(",")]
    if args.measure:
        print(json.dumps(measure(envs, batches)))
        return 0
    if args.before is None or args.after is None:
        p.error("give BEFORE_SRC and AFTER_SRC")
    rates: dict[tuple[str, int], dict[str, dict[str, list[float]]]] = {}
    for r in range(args.rounds):
        for label, src in (("before", args.before), ("after", args.after)):
            print(f"round {r + 1}/{args.rounds}: {label} ({src})", flush=True)
            proc = subprocess.run([sys.executable, __file__, "--measure", "--envs", args.envs, "--batch-sizes", args.batch_sizes],
                                  env={**os.environ, "PYTHONPATH": str(src.resolve())}, check=True, capture_output=True, text=True)
            for row in json.loads(proc.stdout.strip().splitlines()[-1]):
                runs = rates.setdefault((row["env"], row["batch"]), {"before": {"env_step": [], "plant_step": []},
                                                                     "after": {"env_step": [], "plant_step": []}})
                for part in ("env_step", "plant_step"):
                    runs[label][part].append(row[part])
    table = []
    print(f"\n{'env':32s} {'batch':>6s} {'env before':>11s} {'env after':>11s} {'ratio':>6s} {'plant before':>13s} "
          f"{'plant after':>12s} {'ratio':>6s}  (env steps/s, medians of {args.rounds})")
    for (env, batch), runs in rates.items():
        med = {label: {part: statistics.median(v) for part, v in parts.items()} for label, parts in runs.items()}
        table.append({"env": env, "batch": batch, **runs, "env_ratio": med["after"]["env_step"] / med["before"]["env_step"],
                      "plant_ratio": med["after"]["plant_step"] / med["before"]["plant_step"]})
        print(f"{env:32s} {batch:6d} {med['before']['env_step']:11,.0f} {med['after']['env_step']:11,.0f} {table[-1]['env_ratio']:6.3f} "
              f"{med['before']['plant_step']:13,.0f} {med['after']['plant_step']:12,.0f} {table[-1]['plant_ratio']:6.3f}")
    if args.out:
        args.out.write_text(json.dumps({"rounds": args.rounds, "steps": STEPS, "rows": table}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
