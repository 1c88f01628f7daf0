"""Env speed of two checkouts in one table: `marinejax bench envs` run alternately from each
checkout's source (rounds of before, after), on the same machine in one session, so that both see
the same load; per env and batch the median env steps/s of each and their ratio.

    python scripts/bench_before_after.py BEFORE_SRC AFTER_SRC [--rounds 3] [--out FILE.json] \
        -- --envs BlueROV2Heavy-StationKeeping --batch-sizes 256,1024 --physics midpoint:1

BEFORE_SRC and AFTER_SRC are the `src` folders of two checkouts (e.g. a `git worktree` of the commit
before a redesign, and this one); the arguments after `--` go to `marinejax bench envs` unchanged
(give one `--physics` variant: a checkout before `--with` existed knows only that option).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path


def bench(src: Path, bench_args: list[str], out: Path) -> list[dict]:
    env = {**os.environ, "PYTHONPATH": str(src.resolve())}
    subprocess.run([sys.executable, "-m", "marinejax.cli", "bench", "envs", *bench_args, "--out", str(out)], env=env,
                   check=True, stdout=subprocess.DEVNULL)
    return json.loads(out.read_text())["rows"]


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    split = argv.index("--") if "--" in argv else len(argv)
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before", type=Path, help="the src folder of the checkout before")
    p.add_argument("after", type=Path, help="the src folder of the checkout after")
    p.add_argument("--rounds", type=int, default=3, help="alternations of before and after (default 3)")
    p.add_argument("--out", type=Path, help="also write every measurement and the table as JSON")
    args = p.parse_args(argv[:split])
    bench_args = argv[split + 1:]
    rates: dict[tuple[str, int], dict[str, list[float]]] = {}
    machine = None
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for label, src in (("before", args.before), ("after", args.after)):
                print(f"round {r + 1}/{args.rounds}: {label} ({src})", flush=True)
                out = Path(tmp) / f"{label}-{r}.json"
                for row in bench(src, bench_args, out):
                    rates.setdefault((row["env"], row["batch"]), {"before": [], "after": []})[label].append(row["env_steps_per_s"])
                machine = machine or json.loads(out.read_text())["machine"]
    table = []
    print(f"\n{'env':40s} {'batch':>6s} {'before steps/s':>15s} {'after steps/s':>15s} {'after/before':>12s}  (medians of {args.rounds})")
    for (env, batch), runs in rates.items():
        before, after = statistics.median(runs["before"]), statistics.median(runs["after"])
        table.append({"env": env, "batch": batch, "before": runs["before"], "after": runs["after"], "ratio": after / before})
        print(f"{env:40s} {batch:6d} {before:15,.0f} {after:15,.0f} {after / before:12.3f}")
    print(f"machine: {machine}")
    if args.out:
        args.out.write_text(json.dumps({"machine": machine, "bench_args": bench_args, "rows": table}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
