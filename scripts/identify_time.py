"""Time of one identification fit, and how much of it is XLA compiling: the BlueROV2 Heavy log of
`tests/test_identify.py`'s first test (every fluid parameter ×0.6 or ×1.4, 120 s of the excitation,
measured by the sensor models), fitted as `marinejax identify` does (the staged fit).

    python scripts/identify_time.py [--out VALUES.npy]

Run with another checkout's package first on PYTHONPATH to compare two versions on one machine;
`--out` keeps the fitted values, their standard deviations and the costs for that comparison.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from collections import defaultdict
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="where to save the fitted values, std and costs (.npy)")
    args = parser.parse_args()
    seconds = defaultdict(float)
    jax.monitoring.register_event_duration_secs_listener(lambda event, secs, **_: seconds.__setitem__(event, seconds[event] + secs))

    import marinejax
    from marinejax.identify import Identifier, excitation, simulate_log
    from marinejax.plant import Plant, PlantConfig
    from test_identify import perturbed

    plant = Plant("bluerov2_heavy", PlantConfig())
    log = simulate_log(plant, perturbed(plant), excitation(plant, duration=120.0, seed=0), seed=1)
    before = dict(seconds)
    t0 = time.perf_counter()
    result = Identifier(plant, log).fit()
    total = time.perf_counter() - t0
    compile_s = seconds["/jax/core/compile/backend_compile_duration"] - before.get("/jax/core/compile/backend_compile_duration", 0.0)
    trace_s = seconds["/jax/core/compile/jaxpr_trace_duration"] - before.get("/jax/core/compile/jaxpr_trace_duration", 0.0)
    print(f"marinejax from {Path(marinejax.__file__).parent}, jax {jax.__version__}, {platform.processor() or platform.machine()}")
    print(f"fit {total:.1f} s: XLA compiling {compile_s:.1f} s, tracing {trace_s:.1f} s; "
          f"cost {result.cost_before:.4g} -> {result.cost_after:.6g} in {result.steps} steps")
    if args.out:
        np.save(args.out, np.concatenate([result.values, result.std, [result.cost_before, result.cost_after]]))


if __name__ == "__main__":
    main()
