"""The `marinejax` command line: `marinejax validate`, `marinejax bench physics`."""

from __future__ import annotations

import argparse
import sys


def _validate(args: argparse.Namespace) -> int:
    from marinejax.validation import print_validation
    from marinejax.vehicle import load_vehicle

    vehicle = load_vehicle(args.vehicle, param_set=args.param_set)
    rows = print_validation(vehicle, dt=args.dt)
    worst = max(abs(m - e) / abs(e) for _, m, e, _ in rows)
    print(f"largest relative difference: {100 * worst:.2f} %")
    return 0 if worst < 0.03 else 1


def _bench(args: argparse.Namespace, rest: list[str]) -> int:
    if args.what == "physics":
        from marinejax.benchmarks.physics import main as bench_main

        return bench_main(rest)
    raise AssertionError(args.what)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="marinejax", description="Underwater vehicles in JAX + MuJoCo MJX.")
    sub = parser.add_subparsers(dest="command", required=True)
    val = sub.add_parser("validate", help="simulate force steps and a roll oscillation; print them against closed-form values")
    val.add_argument("--vehicle", default="bluerov2_heavy", help="vehicle name (see marinejax.list_vehicles())")
    val.add_argument("--param-set", default=None, help="named parameter set of the vehicle (default: the vehicle's default)")
    val.add_argument("--dt", type=float, default=0.01, help="physics step in seconds (default 0.01)")
    bench = sub.add_parser("bench", help="benchmarks; extra flags go to the benchmark (see `marinejax bench physics -h`)")
    bench.add_argument("what", choices=["physics"])
    args, rest = parser.parse_known_args(argv)
    if args.command != "bench" and rest:
        parser.error(f"unrecognized arguments: {' '.join(rest)}")
    try:
        if args.command == "validate":
            if not (0 < args.dt <= 0.05):
                parser.error(f"--dt must be in (0, 0.05] s, got {args.dt}")
            return _validate(args)
        return _bench(args, rest)
    except (ValueError, FileNotFoundError) as err:
        print(f"marinejax: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
