"""Shared pieces of the benchmarks: machine description, fair timing, number formatting."""

from __future__ import annotations

import argparse
import math
import time

MIN_TIMED_CALLS = 5  # timed calls per variant (after the compiling one), at least ...
MIN_TIMED_SECONDS = 0.5  # ... and until this much time has been measured
MAX_TIMED_CALLS = 50


def time_calls(fns: dict) -> dict:
    """Time several jitted calls fairly: one untimed call of each (compile + warm-up), then timed
    calls of each in turn (interleaved, so machine noise hits all alike) until each has at least
    MIN_TIMED_CALLS calls and MIN_TIMED_SECONDS of measured time. Reports the best call of each."""
    import jax

    first = {}
    for name, fn in fns.items():
        start = time.perf_counter()
        jax.block_until_ready(fn())
        first[name] = time.perf_counter() - start
    times = {name: [] for name in fns}

    def enough(ts):
        return len(ts) >= MAX_TIMED_CALLS or (len(ts) >= MIN_TIMED_CALLS and sum(ts) >= MIN_TIMED_SECONDS)

    while not all(enough(ts) for ts in times.values()):
        for name, fn in fns.items():
            start = time.perf_counter()
            jax.block_until_ready(fn())
            times[name].append(time.perf_counter() - start)
    out = {}
    for name, ts in times.items():
        best = min(ts)
        out[name] = {"seconds": best, "calls": len(ts), "mean_seconds": sum(ts) / len(ts),
                     "compile_seconds": max(first[name] - best, 0.0)}
    return out


def parse_batch_sizes(text: str) -> list[int]:
    sizes = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        try:
            b = int(part)
        except ValueError:
            raise argparse.ArgumentTypeError(f"batch sizes must be positive integers, got {part!r}") from None
        if b < 1:
            raise argparse.ArgumentTypeError(f"batch sizes must be positive integers, got {b}")
        sizes.append(b)
    if not sizes:
        raise argparse.ArgumentTypeError("no batch sizes given")
    return sizes


def positive(kind):
    def parse(text: str):
        try:
            x = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a positive {kind.__name__}, got {text!r}") from None
        if not (math.isfinite(x) and x > 0):
            raise argparse.ArgumentTypeError(f"expected a positive {kind.__name__}, got {text!r}")
        return x

    return parse


def fmt_rate(x: float) -> str:
    if x >= 1e9:
        return f"{x / 1e9:.2f} G"
    if x >= 1e6:
        return f"{x / 1e6:.2f} M"
    if x >= 1e3:
        return f"{x / 1e3:.1f} k"
    return f"{x:.1f}"
