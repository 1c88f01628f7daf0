"""Training display: env steps, steps/s, evaluation return, position error, elapsed, time left.

On a terminal a live bar; in a file or pipe one plain line per evaluation, for example
`eval step=634880/12000000 elapsed_s=44.1 steps_per_s=21456 return=-12.30 error_m=0.0123 best_error_m=0.0101`
(fields `key=value`, `-` where not known yet)."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from marinejax.train.curves import evaluation_error
from marinejax.train.hyperparams import TrainConfig


class TrainingProgress:
    """Context manager; `update(record)` takes the records `runner.train` passes after each evaluation.

    Position error is the statistic of `marinejax eval` (the task's window: last 1 s of station
    keeping, after 2 s of tracking), averaged over the evaluation episodes; "best" is the lowest so far.
    The live bar is used only when `console` is a terminal."""

    def __init__(self, console: Console, config: TrainConfig):
        self.total = config.agent.num_timesteps
        self.episode_length = None
        self.progress = Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("env steps · {task.fields[sps]} steps/s · return {task.fields[ret]} · pos. error {task.fields[err]}"),
            TimeElapsedColumn(),
            TextColumn("left"),
            TimeRemainingColumn(),
            console=console,
            transient=False,
        )
        self.task = None
        self.console = console
        self.last_step, self.last_time = 0, 0.0
        self.best = None
        self.live = console.is_terminal
        self._open = False  # the live display is showing

    def __enter__(self) -> "TrainingProgress":
        if self.live:
            self._open = True
            self.progress.__enter__()
            self.task = self.progress.add_task("training", total=self.total, sps="-", ret="-", err="-")
        return self

    def __exit__(self, *exc) -> None:
        self.stop(*exc)

    def stop(self, *exc) -> None:
        """Close the live display (once): training has ended."""
        if self._open:
            self._open = False
            self.progress.__exit__(*(exc or (None, None, None)))

    def update(self, record: dict[str, Any]) -> None:
        step, elapsed = record["step"], record["elapsed"]
        sps = record.get("training/sps")
        if sps is None and step > self.last_step and elapsed > self.last_time:
            sps = (step - self.last_step) / (elapsed - self.last_time)
        self.last_step, self.last_time = step, elapsed
        err = evaluation_error(record)
        if err is not None and record["step"] > 0:
            self.best = err if self.best is None else min(self.best, err)
        ret = record.get("eval/episode_reward")
        if not self.live:
            self.console.print(
                f"eval step={step}/{self.total} elapsed_s={elapsed:.1f} steps_per_s={f'{sps:.0f}' if sps else '-'} "
                f"return={f'{ret:.2f}' if ret is not None else '-'} error_m={f'{err:.4f}' if err is not None else '-'} "
                f"best_error_m={f'{self.best:.4f}' if self.best is not None else '-'}",
                markup=False,
            )
            return
        self.progress.update(
            self.task,
            completed=min(step, self.total),
            sps=f"{sps:,.0f}" if sps else "-",
            ret=f"{ret:.1f}" if ret is not None else "-",
            err=f"{err:.4f} m (best {self.best:.4f})" if err is not None and self.best is not None
            else (f"{err:.4f} m" if err is not None else "-"),
        )
