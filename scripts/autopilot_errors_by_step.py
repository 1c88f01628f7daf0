"""Which set-point changes an autopilot policy leaves unsettled (developer tool, not installed).

    python scripts/autopilot_errors_by_step.py RUN_OR_CHECKPOINT_OR_SHIPPED_NAME

Flies the policy on its env's 64 evaluation episodes (seed 12345) and prints the mean |depth error|
(m, as observed: clipped to the env's depth_clip) over the last `settled` s of the second set-point's
segment, split by that segment's depth step (dives and climbs of more than 5 m, smaller changes),
then the ten worst episodes with their set-points.
"""

from __future__ import annotations

import sys

import jax
import numpy as np

from marinejax.control import policy_controller, rollout
from marinejax.train.checkpoints import load_policy


def main(source: str) -> None:
    _, env, policy, ckpt = load_policy(source)
    c = env.config
    if type(env).__name__ != "Autopilot" or c.segments < 2:
        raise SystemExit(f"{source}: not an autopilot env with two or more set-points")
    keys = jax.random.split(jax.random.PRNGKey(12345), 64)
    # observation [0]: the depth error (m, clipped to ±depth_clip) to the set-point of the next step
    _, depth_error = rollout(env, policy_controller(jax.jit(policy)), keys, record=lambda s: s.obs[0])
    task = jax.vmap(env.reset)(keys).info["task"]
    per_segment, window = round(c.segment_duration / c.control_dt), round(c.settled / c.control_dt)
    err = np.abs(np.asarray(depth_error))
    # record k is taken after step k + 1 and looks at step k + 2's set-point: a segment's last window
    # ends one record before its last step
    end1 = err[:, per_segment - 1 - window:per_segment - 1].mean(1)
    end2 = err[:, 2 * per_segment - 1 - window:2 * per_segment - 1].mean(1)
    depth, heading, speed = (np.asarray(x) for x in (task.depth, task.heading, task.speed))
    step = depth[:, 1] - depth[:, 0]  # m, world z up: negative is a dive
    print(f"{source} ({ckpt.name}): second segment, mean |depth error| over its last {c.settled:g} s")
    for label, sel in (("dives > 5 m", step < -5), ("climbs > 5 m", step > 5), ("changes within 5 m", np.abs(step) <= 5)):
        print(f"  {label:20s} {sel.sum():2d} episodes: {end2[sel].mean():.3f} m" if sel.any() else f"  {label:20s}  0 episodes")
    print("  worst episodes: error m | speed set-points m/s | depth step m | heading step ° | first segment's error m")
    for i in np.argsort(-end2)[:10]:
        print(f"  {i:2d}: {end2[i]:.3f} | {speed[i, 0]:.2f}, {speed[i, 1]:.2f} | {step[i]:+.2f} | "
              f"{np.degrees(heading[i, 1] - heading[i, 0]):+.0f} | {end1[i]:.3f}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    main(sys.argv[1])
