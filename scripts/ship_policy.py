"""Copy a trained run into the package as a shipped policy (developer tool, not installed).

    python scripts/ship_policy.py RUN_DIR [RUN_DIR ...]

For each run directory (e.g. seed 0 of `marinejax bench training ENV --seeds 5`), copies its
config.json, metrics.jsonl, best.json and best checkpoint (only that one, to keep the wheel small)
into src/marinejax/policies/<ENV>/, then evaluates the shipped copy exactly as
tests/train/test_learning.py does (64 episodes, seed 12345, no video) and writes eval.json there.
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from pathlib import Path

POLICIES = Path(__file__).resolve().parents[1] / "src" / "marinejax" / "policies"


def ship(run_dir: Path) -> Path:
    from marinejax.train.evaluate import evaluate_run
    from marinejax.train.checkpoints import BEST, CHECKPOINTS, best_checkpoint

    run_dir = Path(run_dir)
    config = json.loads((run_dir / "config.json").read_text())
    ckpt = best_checkpoint(run_dir)
    if ckpt is None:
        raise SystemExit(f"{run_dir} has no best.json naming a complete checkpoint")
    dest = POLICIES / config["env"]
    shutil.rmtree(dest, ignore_errors=True)
    (dest / CHECKPOINTS).mkdir(parents=True)
    for name in ("config.json", "metrics.jsonl", BEST):
        shutil.copy2(run_dir / name, dest / name)
    shutil.copytree(ckpt, dest / CHECKPOINTS / ckpt.name)
    with tempfile.TemporaryDirectory() as tmp:
        result = evaluate_run(dest, out_dir=Path(tmp), episodes=64, seed=12345, video=False)
    result.pop("plot", None)
    result["checkpoint"] = f"{CHECKPOINTS}/{ckpt.name}"
    (dest / "eval.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"{config['env']}: shipped {ckpt.name}, mean error {result['position_error_mean_m'] * 1000:.2f} mm, "
          f"success {100 * result['success_rate']:.0f} %")
    return dest


if __name__ == "__main__":
    for arg in sys.argv[1:]:
        ship(Path(arg))
