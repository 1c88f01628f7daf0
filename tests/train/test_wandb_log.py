"""`marinejax train --wandb`: the W&B run a run directory logs to (the CLI's end-to-end check, with a
stand-in package, is in test_cli.py)."""

import importlib.util
import json
import sys
from pathlib import Path

import pytest

from marinejax.errors import UserError
from marinejax.train import wandb_log

# the stand-in package, loaded under its own name whether or not wandb is installed
_spec = importlib.util.spec_from_file_location("fake_wandb", Path(__file__).parent / "fake_wandb" / "wandb" / "__init__.py")
fake_wandb = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fake_wandb)


@pytest.fixture
def fake(monkeypatch):
    monkeypatch.setitem(sys.modules, "wandb", fake_wandb)


def test_without_the_package_it_is_a_user_error_naming_the_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "wandb", None)  # import wandb raises ImportError
    with pytest.raises(UserError, match=r"--wandb needs the wandb package: pip install wandb"):
        wandb_log.check("marinejax")


@pytest.mark.parametrize("project", ["", "team/project"])
def test_a_bad_project_name_is_a_user_error(project, fake):
    with pytest.raises(UserError, match=f"--wandb: '{project}' is not a W&B project name"):
        wandb_log.check(project)


def test_a_resumed_run_directory_logs_to_its_w_and_b_run_and_a_new_one_to_a_new_run(tmp_path, fake):
    first = wandb_log.start("p", tmp_path, {"env": "E"}, resume=False)
    run_id = (tmp_path / wandb_log.ID_FILE).read_text().strip()
    wandb_log.log(first, {"step": 100, "elapsed": 2.0, "eval/episode_window_error": 0.5})
    wandb_log.start("p", tmp_path, {"env": "E"}, resume=True)
    assert (tmp_path / wandb_log.ID_FILE).read_text().strip() == run_id
    wandb_log.start("p", tmp_path, {"env": "E"}, resume=False)  # a run directory started over: a new W&B run
    new_id = (tmp_path / wandb_log.ID_FILE).read_text().strip()
    calls = [json.loads(line) for line in (tmp_path / "fake_wandb.jsonl").read_text().splitlines()]
    assert [c["id"] for c in calls if c["call"] == "init"] == [run_id, run_id, new_id] and new_id != run_id
    assert calls[1] == {"call": "log", "data": {"elapsed": 2.0, "eval/episode_window_error": 0.5}, "step": 100}


def test_the_real_package_offline_writes_the_run_under_the_run_directory(tmp_path, monkeypatch):
    pytest.importorskip("wandb", reason="the optional wandb package is not installed")
    monkeypatch.setenv("WANDB_MODE", "offline")
    monkeypatch.setenv("WANDB_SILENT", "true")
    run = wandb_log.start("marinejax-test", tmp_path, {"env": "E"}, resume=False)
    for step in (0, 100):
        wandb_log.log(run, {"step": step, "eval/episode_window_error": 1.0 / (step + 1)})
    run.finish()
    run_id = (tmp_path / wandb_log.ID_FILE).read_text().strip()
    assert run.id == run_id and list((tmp_path / "wandb").glob(f"offline-run-*-{run_id}/run-{run_id}.wandb"))
