"""Weights & Biases logging of a training run's evaluations (`marinejax train --wandb PROJECT`).

Optional: needs the `wandb` package (`pip install wandb`); where it is not installed, asking for it
is a UserError. The W&B run's id is kept in the run directory (`wandb_id.txt`), so that a resumed
run (`--resume`) goes on logging into the same W&B run (W&B drops steps at or below its newest:
the evaluations a resume repeats after the checkpoint keep their first values there, where
metrics.jsonl and TensorBoard replace them). W&B's own settings apply (`wandb login`,
or `WANDB_MODE=offline` to write the run under the run directory for a later `wandb sync`).
"""

from __future__ import annotations

import uuid
from pathlib import Path
from typing import Any

from marinejax.errors import UserError

ID_FILE = "wandb_id.txt"  # in the run directory: the W&B run's id


def check(project: str) -> Any:
    """The wandb module, once `project` is a valid name and the package is installed (else a UserError)."""
    if not project or "/" in project:
        raise UserError(f"--wandb: {project!r} is not a W&B project name (a name without '/')")
    try:
        import wandb
    except ImportError:
        raise UserError("--wandb needs the wandb package: pip install wandb (TensorBoard files are written "
                        "to the run directory's tensorboard/ without it)") from None
    return wandb


def start(project: str, run_dir: Path, config: dict[str, Any], resume: bool) -> Any:
    """A W&B run for `run_dir` in `project`, named after the run directory, with the training
    config; a resumed run directory continues the W&B run it logged to before (its id file)."""
    wandb = check(project)
    id_file = run_dir / ID_FILE
    run_id = id_file.read_text().strip() if resume and id_file.exists() else uuid.uuid4().hex[:12]
    id_file.write_text(run_id + "\n")
    return wandb.init(project=project, name=run_dir.name, id=run_id, resume="allow", config=config, dir=str(run_dir))


def log(run: Any, record: dict[str, float]) -> None:
    """One evaluation's record (runner's: 'step' in env steps, 'elapsed' in s, the metrics)."""
    run.log({key: value for key, value in record.items() if key != "step"}, step=int(record["step"]))
