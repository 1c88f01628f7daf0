"""Training split over several CPU devices of one host and over several processes (jax.distributed),
through the console script."""

import json
import math
import os
import socket
import subprocess
import sys

import jax
import numpy as np
import pytest
from cli_runner import CACHE_HOME, TINY, marinejax, traced


@pytest.mark.slow
def test_training_on_two_cpu_devices_splits_the_batch_and_learns(tmp_path):
    # the recipe's cpu_devices: the CLI splits the host into two JAX devices before JAX starts
    run = tmp_path / "two"
    proc = marinejax("train", "BlueROV2Heavy-CircleTracking", "--run-dir", str(run), "--no-video", "--ppo", "cpu_devices=2",
                     "--timesteps", "300000", "--episodes", "8", "--ppo", "num_envs=64", "--ppo", "batch_size=64",
                     "--ppo", "num_evals=4", "--ppo", "num_eval_envs=8", timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert any(name.startswith("step-") for name in traced())  # kept under the devices' pmap too
    assert "64 envs on 2 cpu device(s)" in proc.stdout
    config = json.loads((run / "config.json").read_text())
    assert len(config["machine"]["devices"]) == 2 and config["ppo"]["cpu_devices"] == 2
    records = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    rewards = [r["eval/episode_reward"] for r in records]
    assert all(math.isfinite(v) for r in records for v in r.values())
    assert rewards[-1] > rewards[0] + 0.2 * abs(rewards[0]), rewards
    summary = json.loads((run / "summary.json").read_text())
    assert summary["devices"] == 2 and math.isfinite(summary["evaluation"]["position_error_mean_m"])


def test_devices_that_do_not_divide_the_envs_or_none_are_user_errors():
    # on a CPU host --devices 3 makes three devices, over which 256 envs do not split
    proc = marinejax("train", "BlueROV2Heavy-StationKeeping", "--devices", "3", timeout=120)
    assert proc.returncode == 2 and "num_envs (256) must be a multiple of the number of devices (3)" in proc.stderr
    proc = marinejax("train", "BlueROV2Heavy-StationKeeping", "--devices", "0", timeout=120)
    assert proc.returncode == 2 and "devices must be between 1 and the 1 local device(s)" in proc.stderr, proc.stderr


@pytest.mark.parametrize("xla_flags, expected", [("", "True 2"), ("--xla_force_host_platform_device_count=3", "False 3")])
def test_cpu_devices_are_made_before_jax_starts_unless_xla_flags_set_them(xla_flags, expected):
    code = ("import jax; from marinejax.train.runner import use_cpu_devices; made = use_cpu_devices(2); "
            "print(made, jax.local_device_count(), use_cpu_devices(4), jax.local_device_count())")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "XLA_FLAGS": xla_flags})
    assert proc.returncode == 0, proc.stderr[-3000:]
    count = expected.split()[1]
    assert proc.stdout.split() == [*expected.split(), "False", count]  # once JAX has started, nothing changes


def test_a_recipe_asking_for_more_cpu_devices_than_jax_started_with_warns_and_uses_those_there_are():
    from marinejax.errors import UserError
    from marinejax.train.hyperparams import PPOConfig
    from marinejax.train.runner import check_devices

    with pytest.warns(UserWarning, match=r"trains on 2 CPU devices but JAX started with 1.*use_cpu_devices\(2\)"):
        assert check_devices(None, PPOConfig(cpu_devices=2)) == 1
    assert check_devices(None, PPOConfig()) == 1
    with pytest.raises(UserError, match="'cpu_devices' must be >= 1, got 0"):
        PPOConfig(cpu_devices=0)


# Training with several processes (jax.distributed)
def test_a_checkpoint_written_by_one_of_several_processes_is_brax_s_own(tmp_path, monkeypatch):
    # Brax saves from process 0 only and orbax's save, as Brax calls it, waits for every process:
    # with several processes marinejax writes the same files from process 0 alone.
    import marinejax as mj
    from marinejax.train import ppo

    env = mj.make("BlueROV2Heavy-StationKeeping")
    config = ppo.Config(policy_hidden=(8,), value_hidden=(8,))
    network = ppo.network_factory(config, env.observation_size)(env.observation_size, env.action_size)
    from brax.training.acme import running_statistics, specs

    keys = jax.random.split(jax.random.PRNGKey(0))
    normalizer = running_statistics.init_state(specs.Array((env.observation_size,), np.dtype("float32")))
    params = (normalizer, network.policy_network.init(keys[0]), network.value_network.init(keys[1]))
    ppo.save(tmp_path / "one", 100, params, env, config)
    monkeypatch.setattr(jax, "process_count", lambda: 2)  # as process 0 of two sees it
    ppo.save(tmp_path / "alone", 100, params, env, config)
    one, alone = tmp_path / "one" / "000000000100", tmp_path / "alone" / "000000000100"
    assert (one / ppo.NETWORK_CONFIG).read_text() == (alone / ppo.NETWORK_CONFIG).read_text()
    monkeypatch.undo()
    for a, b in zip(jax.tree.leaves(ppo.load(one)), jax.tree.leaves(ppo.load(alone)), strict=True):
        np.testing.assert_array_equal(a, b)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_two_processes_train_one_policy_and_process_0_writes_the_run(tmp_path):
    run = tmp_path / "run"
    port = _free_port()
    env = {"PYTHONUNBUFFERED": "1", "XDG_CACHE_HOME": str(CACHE_HOME)}
    procs = [subprocess.Popen([sys.executable, "-m", "marinejax.cli", "train", "BlueROV2Heavy-StationKeeping", "--run-dir", str(run),
                               *TINY, "--no-video", "--coordinator", f"127.0.0.1:{port}", "--num-processes", "2", "--process-id", str(i)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env={**os.environ, **env})
             for i in (0, 1)]
    outs = [p.communicate(timeout=900) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err[-3000:]
    assert "8 envs on 1 cpu device(s) × 2 processes" in outs[0][0]
    assert "process 1 of 2: done" in outs[1][0] and f"evaluate the run in one process, `marinejax eval {run}`" in outs[0][0]
    # Brax ends by asserting that every process holds the same parameters: the gradients were averaged
    config = json.loads((run / "config.json").read_text())
    assert config["processes"] == 2
    records = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert len(records) == 3 and records[-1]["step"] >= 1600  # one process's evaluations, not two
    checkpoints = sorted((run / "checkpoints").iterdir())
    assert len(checkpoints) == 2 and (checkpoints[-1] / "ppo_network_config.json").exists()
    assert json.loads((run / "summary.json").read_text())["status"] == "finished"
    proc = marinejax("eval", str(run), "--no-video", "--episodes", "4")  # then, in one process
    assert proc.returncode == 0 and (run / "eval" / "eval.json").exists(), proc.stderr[-3000:]
