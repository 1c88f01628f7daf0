"""Env throughput: full env steps (thrusters, hydrodynamics, observation, reward) per second.

    marinejax bench envs [--envs BlueROV2Heavy-StationKeeping,...] [--batch-sizes 1,256,1024,4096,8192]

Random actions in [−1, 1]; each timed call is a jitted, vmapped `lax.scan` over `--steps` env steps
(compilation excluded). env steps/s = batch × steps / seconds; real-time factor = env steps/s ×
control period (simulated seconds per wall second, summed over the batch).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from marinejax.benchmarks.common import fmt_rate, machine_info, parse_batch_sizes, positive, time_calls

DEFAULT_ENVS = "BlueROV2Heavy-StationKeeping,BlueROV2Heavy-CircleTracking,BlueROV2Heavy-HelixTracking,BlueROV2Heavy-LemniscateTracking"
DEFAULT_BATCHES = "1,256,1024,4096,8192"
MAX_ENV_STEPS_PER_CALL = 8192 * 10  # batch × steps cap per timed call: big batches take fewer steps


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="marinejax bench envs", description=__doc__.splitlines()[0])
    p.add_argument("--envs", default=DEFAULT_ENVS, help="comma-separated env names (default: the four Heavy tasks)")
    p.add_argument("--batch-sizes", type=parse_batch_sizes, default=parse_batch_sizes(DEFAULT_BATCHES),
                   help=f"comma-separated batch sizes (default {DEFAULT_BATCHES})")
    p.add_argument("--steps", type=positive(int), default=20, help="env steps per timed call (default 20, fewer for big batches)")
    p.add_argument("--out", type=Path, default=None, help="also write the results as JSON to this path")
    return p


def time_env(env, batch: int, steps: int) -> dict:
    import jax
    import jax.numpy as jnp

    def run(state, key):
        def body(s, k):
            return env.step(s, jax.random.uniform(k, (env.action_size,), minval=-1.0, maxval=1.0)), None

        return jax.lax.scan(body, state, jax.random.split(key, steps))[0]

    reset = jax.jit(jax.vmap(env.reset))
    run_b = jax.jit(jax.vmap(run))
    state = reset(jax.random.split(jax.random.PRNGKey(0), batch))
    keys = jax.random.split(jax.random.PRNGKey(1), batch)
    timed = time_calls({"env": lambda: run_b(state, keys).obs})["env"]
    final = run_b(state, keys)
    timed["finite"] = bool(jnp.all(jnp.isfinite(final.obs)))
    return timed


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from rich.console import Console
    from rich.table import Table

    import marinejax.envs as E

    names = [n.strip() for n in args.envs.split(",") if n.strip()]
    console = Console() if sys.stdout.isatty() else Console(width=140)
    try:
        envs = {n: E.make(n) for n in names}
    except ValueError as err:
        print(f"marinejax bench envs: error: {err}", file=sys.stderr)
        return 2
    info = machine_info()
    console.print("[bold]marinejax env benchmark[/bold]")
    console.print(f"machine: {info['cpu']} | {info['cpu_count']} cores | jax {info['jax']} {info['backend']} {info['devices']}"
                  + (f" | load average {info['load_average'][0]:.2f} at start" if info["load_average"] else ""))
    start = time.perf_counter()
    table = Table(title="env steps per second (random actions, full step: thrusters, hydrodynamics, observation, reward)")
    for col in ("env", "control dt × substeps", "batch", "steps/call", "env steps/s", "real-time factor", "compile s"):
        table.add_column(col, justify="left" if col == "env" else "right")
    rows = []
    for name, env in envs.items():
        c = env.config
        for batch in args.batch_sizes:
            steps = max(1, min(args.steps, MAX_ENV_STEPS_PER_CALL // batch))
            t = time_env(env, batch, steps)
            rate = batch * steps / t["seconds"]
            rows.append({"env": name, "batch": batch, "steps": steps, "env_steps_per_s": rate,
                         "real_time_factor": rate * c.control_dt, "control_dt": c.control_dt, "substeps": c.substeps, **t})
            table.add_row(name, f"{c.control_dt:g} s × {c.substeps}", str(batch), str(steps), fmt_rate(rate),
                          fmt_rate(rate * c.control_dt), f"{t['compile_seconds']:.1f}")
            if not t["finite"]:
                console.print(f"[red]{name} batch {batch}: non-finite observations[/red]")
    console.print(table)
    console.print(f"total benchmark time {time.perf_counter() - start:.0f} s")
    if args.out:
        args.out.write_text(json.dumps({"machine": info, "rows": rows}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
