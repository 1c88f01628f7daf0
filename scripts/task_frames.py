"""One video frame of each kind of task, tiled into the README's picture (docs/images/tasks.png).

    python scripts/task_frames.py [--out docs/images/tasks.png] [--work DIR]

Each tile is a frame of the first evaluation episode (`marinejax eval`, its video) of the shipped
policy or, for a task without one, of its classical controller, two thirds into it (obstacle
avoidance: a tenth, among the piles; torpedo docking: a third, as it latches at 20 s and then flies
on through the open tube). Takes about 10 minutes on a 2-core CPU (each evaluation
compiles and renders); with --work, an evaluation whose video is already there is reused.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

# (env, classical controller or "" for the shipped policy, caption, where in the episode)
TASKS = (
    ("BlueROV2Heavy-StationKeeping", "", "ROV station keeping (PPO)", 2 / 3),
    ("BlueROV2Heavy-CircleTracking", "", "ROV circle tracking (PPO)", 2 / 3),
    ("BlueROV2Heavy-Docking", "pid", "ROV docking (PID)", 2 / 3),
    ("BlueROV2Heavy-ObstacleAvoidance", "avoid", "ROV obstacle avoidance (reactive)", 0.1),
    ("Remus100-Autopilot", "", "torpedo autopilot (PPO)", 2 / 3),
    ("Remus100-CircleFollowing", "", "torpedo circle following (PPO)", 2 / 3),
    ("Remus100-Docking", "los", "torpedo docking (line of sight)", 0.33),
    ("Remus100-TerrainFollowing", "autopilot", "torpedo terrain following (autopilot)", 2 / 3),
)


def frame_of(env: str, controller: str, work: Path, where: float):
    import imageio.v3 as iio

    out = work / env
    if not any(out.glob("episode0.*")):
        cmd = ["marinejax", "eval", env, "--episodes", "2", "--out", str(out)] + (["--controller", controller] if controller else [])
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    frames = iio.imread(next(out.glob("episode0.*")), index=None)
    return frames[int(where * len(frames))]


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/images/tasks.png")
    parser.add_argument("--work", default=None, help="where the evaluations are written (default: a temporary directory)")
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.work or tmp)
        fig, axes = plt.subplots(2, 4, figsize=(16, 6.4))
        for ax, (env, controller, caption, where) in zip(axes.flat, TASKS):
            print(f"{env} ...", flush=True)
            ax.imshow(frame_of(env, controller, work, where))
            ax.set_title(caption, fontsize=11)
            ax.axis("off")
        fig.tight_layout()
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.out, dpi=60)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
