"""Env throughput: full env steps (thrusters, hydrodynamics, observation, reward) per second.

    marinejax bench envs [--envs BlueROV2Heavy-StationKeeping,...] [--batch-sizes 1,256,1024,4096,8192]
                         [--physics midpoint:1,euler:5 | --with KEY=VALUE ...]

Random actions in [−1, 1]; each timed call is a jitted, vmapped `lax.scan` over `--steps` env steps
(compilation excluded). env steps/s = batch × steps / seconds; real-time factor = env steps/s ×
control period (simulated seconds per wall second, summed over the batch). Each `--physics` variant
(integrator:substeps) is the same env with only those two settings changed, timed in the same run;
the speed-up column compares each with the last variant (by default the first-order 5 × 10 ms
scheme that was the default before the midpoint integrator). With `--with KEY=VALUE ...` the two
variants are instead the env as registered and the env with those settings, the ratio against the
former: `--with sensors.sonar.enabled=true` prices the sonar, whose ray casts per second are shown.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from marinejax.benchmarks.common import fmt_rate, parse_batch_sizes, positive, time_calls
from marinejax.config import parse_key_values
from marinejax.console import make_console
from marinejax.errors import UserError
from marinejax.machine import machine_info

DEFAULT_ENVS = "BlueROV2Heavy-StationKeeping,BlueROV2Heavy-CircleTracking,BlueROV2Heavy-HelixTracking,BlueROV2Heavy-LemniscateTracking"
DEFAULT_BATCHES = "1,256,1024,4096,8192"
DEFAULT_PHYSICS = "midpoint:1,euler:5"
MAX_ENV_STEPS_PER_CALL = 8192 * 10  # batch × steps cap per timed call: big batches take fewer steps


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="marinejax bench envs", description=__doc__.splitlines()[0])
    p.add_argument("--envs", default=DEFAULT_ENVS, help="comma-separated env names (default: the four Heavy tasks)")
    p.add_argument("--batch-sizes", type=parse_batch_sizes, default=parse_batch_sizes(DEFAULT_BATCHES),
                   help=f"comma-separated batch sizes (default {DEFAULT_BATCHES})")
    p.add_argument("--physics", type=parse_physics, default=parse_physics(DEFAULT_PHYSICS),
                   help=f"comma-separated integrator:substeps variants to compare (default {DEFAULT_PHYSICS})")
    p.add_argument("--with", dest="with_", action="append", metavar="KEY=VALUE",
                   help="compare the env as registered with the env with these settings (instead of --physics)")
    p.add_argument("--steps", type=positive(int), default=20, help="env steps per timed call (default 20, fewer for big batches)")
    p.add_argument("--out", type=Path, default=None, help="also write the results as JSON to this path")
    return p


def parse_physics(text: str) -> list[tuple[str, int]]:
    """'midpoint:1,euler:5' → [("midpoint", 1), ("euler", 5)] (argparse type)."""
    from marinejax.physics import INTEGRATORS

    out = []
    for item in (t.strip() for t in text.split(",") if t.strip()):
        name, _, n = item.partition(":")
        if name not in INTEGRATORS or not n.isdigit() or int(n) < 1:
            raise argparse.ArgumentTypeError(
                f"bad physics variant {item!r}: expected INTEGRATOR:SUBSTEPS with INTEGRATOR in {list(INTEGRATORS)}")
        out.append((name, int(n)))
    if not out:
        raise argparse.ArgumentTypeError("no physics variant given")
    return out


def time_env(env, batch: int, steps: int) -> dict:
    import jax
    import jax.numpy as jnp

    from marinejax.control import random_controller, run_steps

    controller = random_controller(env.action_size)

    def run(state, key):
        return run_steps(env, controller, state, controller.init(key), steps)[0]

    reset = jax.jit(jax.vmap(env.reset))
    run_b = jax.jit(jax.vmap(run))
    state = reset(jax.random.split(jax.random.PRNGKey(0), batch))
    keys = jax.random.split(jax.random.PRNGKey(1), batch)
    timed = time_calls({"env": lambda: run_b(state, keys).obs})["env"]
    final = run_b(state, keys)
    timed["finite"] = bool(jnp.all(jnp.isfinite(final.obs)))
    return timed


def rays_per_step(env) -> int:
    """Rays an env casts per step: every scene sensor's, each step (a slower sensor holds its reading
    but is cast anyway, as batched code cannot skip it)."""
    return sum(int(s.directions.size // 3) for s in env.plant.scene_sensors.sensors.values())


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from rich.table import Table

    import marinejax.envs as E

    names = [n.strip() for n in args.envs.split(",") if n.strip()]
    console = make_console()
    try:
        if args.with_:
            with_ = parse_key_values(args.with_, "--with")
            variants = {"as registered": {}, " ".join(args.with_): with_}
            base = "as registered"
        else:
            variants = {f"{integ}:{sub}": {"integrator": integ, "substeps": sub} for integ, sub in args.physics}
            base = f"{args.physics[-1][0]}:{args.physics[-1][1]}"
        envs = {(n, label): E.make(n, **overrides) for n in names for label, overrides in variants.items()}
    except UserError as err:
        print(f"marinejax bench envs: error: {err}", file=sys.stderr)
        return 2
    info = machine_info()
    console.print("[bold]marinejax env benchmark[/bold]")
    console.print(f"machine: {info['cpu']} | {info['cpu_count']} cores | jax {info['jax']} {info['backend']} {info['devices']}"
                  + (f" | load average {info['load_average'][0]:.2f} at start" if info["load_average"] else ""))
    start = time.perf_counter()
    table = Table(title="env steps per second (random actions, full step: thrusters, hydrodynamics, observation, reward)")
    for col in ("env", "variant", "batch", "steps/call", "env steps/s", "real-time factor", "rays/s", f"vs {base}", "compile s"):
        table.add_column(col, justify="left" if col == "env" else "right")
    rows = []
    for name in names:
        for batch in args.batch_sizes:
            steps = max(1, min(args.steps, MAX_ENV_STEPS_PER_CALL // batch))
            # time the baseline first so that every variant's ratio uses a rate measured just before it
            measured = {}
            for label in [base] + [v for v in variants if v != base]:
                t = time_env(envs[(name, label)], batch, steps)
                measured[label] = (t, batch * steps / t["seconds"])
            for label in variants:
                t, rate = measured[label]
                env = envs[(name, label)]
                c = env.config
                ratio = rate / measured[base][1]
                rays = rate * rays_per_step(env)
                rows.append({"env": name, "variant": label, "overrides": variants[label], "batch": batch, "steps": steps,
                             "env_steps_per_s": rate, "real_time_factor": rate * c.control_dt, "control_dt": c.control_dt,
                             "rays_per_s": rays, "speedup_vs_baseline": ratio, "baseline": base, **t})
                table.add_row(name, f"{label} ({c.integrator} {c.control_dt:g} s × {c.substeps})", str(batch), str(steps),
                              fmt_rate(rate), fmt_rate(rate * c.control_dt), fmt_rate(rays) if rays else "-", f"{ratio:.2f}×",
                              f"{t['compile_seconds']:.1f}")
                if not t["finite"]:
                    console.print(f"[red]{name} {label} batch {batch}: non-finite observations[/red]")
    console.print(table)
    console.print(f"total benchmark time {time.perf_counter() - start:.0f} s")
    if args.out:
        args.out.write_text(json.dumps({"machine": info, "rows": rows}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
