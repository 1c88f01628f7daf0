"""A stand-in for the wandb package in the CLI tests (put first on PYTHONPATH): it records what
marinejax asks of W&B in <dir>/fake_wandb.jsonl, one JSON object a call, instead of logging."""

import json
from pathlib import Path


class Run:
    def __init__(self, path: Path):
        self._path = path

    def write(self, **entry):
        with self._path.open("a") as f:
            f.write(json.dumps(entry) + "\n")

    def log(self, data, step):
        self.write(call="log", data=data, step=step)

    def finish(self):
        self.write(call="finish")


def init(project, name, id, resume, config, dir):  # noqa: A002 (wandb's own argument names)
    run = Run(Path(dir) / "fake_wandb.jsonl")
    run.write(call="init", project=project, name=name, id=id, resume=resume, env=config["env"])
    return run
