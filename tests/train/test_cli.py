"""End to end through the console script: train → eval → resume, SAC, the benchmarks, and user
mistakes (several devices and processes: test_cli_hosts.py)."""

import json
import math
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from cli_runner import CACHE_HOME, TINY, TRACED, marinejax, traced

# --wandb through a stand-in for the wandb package that records its calls (fake_wandb/)
FAKE_WANDB = {"PYTHONPATH": os.pathsep.join([str(Path(__file__).parent / "fake_wandb"), *filter(None, [os.environ.get("PYTHONPATH")])])}


def wandb_calls(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "fake_wandb.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    run = tmp_path_factory.mktemp("runs") / "sk"
    # a relative run directory, as users type it; the linear learning-rate schedule, through Brax's
    # optimizer here and in the resumed run (test_learning_rate.py checks its values)
    proc = marinejax("train", "BlueROV2Heavy-StationKeeping", "--run-dir", "sk", *TINY, "--ppo", "learning_rate_schedule=linear",
                     "--wandb", "marinejax-test", cwd=run.parent, extra_env=FAKE_WANDB)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run.parent / "train.stdout").write_text(proc.stdout)
    return run


@pytest.mark.slow
def test_train_writes_a_complete_run_directory(run_dir):
    for name in ("config.json", "metrics.jsonl", "curve.png", "summary.json", "eval/eval.json", "eval/paths.png"):
        assert (run_dir / name).exists(), name
    config = json.loads((run_dir / "config.json").read_text())
    assert config["env"] == "BlueROV2Heavy-StationKeeping" and config["ppo"]["num_envs"] == 8
    assert config["ppo"]["learning_rate_schedule"] == "linear" and config["ppo"]["decay_start"] == 0.5
    assert config["env_config"]["episode_length"] == 20
    records = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]
    assert [r["step"] for r in records] == sorted(r["step"] for r in records) and records[-1]["step"] >= 1600
    assert "eval/episode_position_error" in records[-1] and "eval/episode_window_error" in records[-1]
    # the scheduled rate as it was at each evaluation, not the float Brax reports (the rate at the start)
    from marinejax.train import ppo
    rates = [(r["step"], r["training/learning_rate"]) for r in records if "training/learning_rate" in r]
    schedule = ppo.Config.from_dict(config["ppo"])
    assert rates and rates[-1][1] < 1e-3
    assert [rate for _, rate in rates] == pytest.approx([float(ppo.learning_rate_at(schedule, step)) for step, _ in rates], rel=1e-6)
    best = json.loads((run_dir / "best.json").read_text())
    assert best["window_error"] == min(r["eval/episode_window_error"] for r in records if r["step"] > 0)
    checkpoints = sorted((run_dir / "checkpoints").iterdir())
    assert len(checkpoints) == 2 and int(checkpoints[-1].name) >= 1600
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["evaluation"]["episodes"] == 4
    video = summary["evaluation"].get("video")
    assert video and Path(video).stat().st_size > 10_000, summary["evaluation"].get("video_error")
    # every evaluation as TensorBoard scalars, the same values as metrics.jsonl
    from tensorboardX.proto import event_pb2

    events = b"".join(p.read_bytes() for p in (run_dir / "tensorboard").glob("events.out.tfevents.*"))
    scalars = []
    while events:  # TFRecord: length (8 bytes), its CRC (4), the event, its CRC (4)
        n = int.from_bytes(events[:8], "little")
        event = event_pb2.Event.FromString(events[12 : 12 + n])
        events = events[16 + n :]
        scalars += [(event.step, v.tag, v.simple_value) for v in event.summary.value]
    logged = sorted((step, value) for step, tag, value in scalars if tag == "eval/episode_window_error")
    assert [step for step, _ in logged] == [r["step"] for r in records]
    np.testing.assert_allclose([v for _, v in logged], [r["eval/episode_window_error"] for r in records], rtol=1e-6)
    # and to W&B (--wandb): one run named after the run directory, its id kept there, the same records
    calls = wandb_calls(run_dir)
    assert calls[0] == {"call": "init", "project": "marinejax-test", "name": "sk", "id": (run_dir / "wandb_id.txt").read_text().strip(),
                        "resume": "allow", "env": "BlueROV2Heavy-StationKeeping"}
    assert calls[-1] == {"call": "finish"} and [c["call"] for c in calls[1:-1]] == ["log"] * len(records)
    assert [c["step"] for c in calls[1:-1]] == [r["step"] for r in records]
    assert [c["data"] for c in calls[1:-1]] == [{k: v for k, v in r.items() if k != "step"} for r in records]


@pytest.mark.slow
def test_output_to_a_pipe_is_one_plain_line_per_evaluation_and_the_compile_cache_is_written(run_dir):
    lines = (run_dir.parent / "train.stdout").read_text().splitlines()
    evals = [line for line in lines if line.startswith("eval ")]
    assert len(evals) == 3, lines  # num_evals=3
    for line in evals:
        assert re.fullmatch(r"eval step=\d+/1600 elapsed_s=\S+ steps_per_s=\S+ return=\S+ error_m=\S+ best_error_m=\S+",
                            line), line
    assert any(line.startswith("run directory: ") and str(run_dir.name) in line for line in lines)
    assert "\x1b" not in "".join(lines)  # no terminal escapes
    cache = CACHE_HOME / "marinejax" / "jax-compilation-cache"
    assert cache.is_dir() and sum(1 for _ in cache.iterdir()) >= 5
    # the batched reset and step, for the 8 training and the 4 evaluation envs
    assert sorted(p.name.split("-")[0] for p in TRACED.iterdir()) == ["reset"] * 2 + ["step"] * 2


@pytest.mark.slow
def test_eval_loads_the_run_and_writes_summary_plot_video(run_dir, tmp_path):
    proc = marinejax("eval", str(run_dir), "--episodes", "3", "--out", str(tmp_path), "--current", "constant", "--randomize")
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads((tmp_path / "eval.json").read_text())
    assert result["episodes"] == 3 and result["env_overrides"] == {"randomization.enabled": True, "current.mode": "constant"}
    assert 0 <= result["position_error_mean_m"] < 10 and (tmp_path / "paths.png").stat().st_size > 10_000
    assert "position error" in proc.stdout
    assert result["units"] == {"heading_error_mean_deg": "°"}
    assert re.search(r"mean over the window: heading error [0-9.]+°\n", proc.stdout), proc.stdout
    assert "best (lowest evaluation error during training)" in proc.stdout
    best = json.loads((run_dir / "best.json").read_text())
    assert result["checkpoint"].endswith(f"{best['step']:012d}")


@pytest.mark.slow
def test_resume_continues_from_the_newest_checkpoint(run_dir, tmp_path):
    run = tmp_path / "interrupted"
    shutil.copytree(run_dir, run)
    newest = sorted((run / "checkpoints").iterdir())[-1]
    shutil.rmtree(newest)  # as if training had stopped before its last checkpoint
    kept = int(sorted((run / "checkpoints").iterdir())[-1].name)
    before = traced()
    logged_before = len(wandb_calls(run))
    proc = marinejax("train", "--resume", str(run), "--episodes", "2", "--no-video", "--wandb", "marinejax-test", extra_env=FAKE_WANDB)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert traced() == before != {}  # this second process loaded the first one's traced env functions
    records = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    steps = [r["step"] for r in records]
    assert steps == sorted(steps) and steps[-1] >= 1600 and kept in steps
    # the same W&B run goes on from the checkpoint's step
    calls = wandb_calls(run)[logged_before:]
    assert calls[0]["call"] == "init" and calls[0]["id"] == wandb_calls(run)[0]["id"]
    assert [c["step"] for c in calls if c["call"] == "log"] == [s for s in steps if s > kept] and calls[-1] == {"call": "finish"}
    assert int(sorted((run / "checkpoints").iterdir())[-1].name) >= 1600


@pytest.mark.parametrize(
    "args,message",
    [
        (["train", "BlueROV2Heavy-Hover"], "unknown env 'BlueROV2Heavy-Hover'"),
        (["train", "BlueROV2Heavy-StationKeeping", "--ppo", "learning_rate=-1"], "'learning_rate' must be > 0"),
        (["train", "BlueROV2Heavy-StationKeeping", "--coordinator", "127.0.0.1:1234"], "--num-processes N and --process-id I together"),
        (["train", "BlueROV2Heavy-StationKeeping", "--coordinator", "127.0.0.1:1234", "--num-processes", "2", "--process-id", "2"],
         "--process-id must be in 0..1"),
        (["train", "BlueROV2Heavy-StationKeeping", "--ppo", "learning_rate_schedule=cosine"],
         "'learning_rate_schedule' must be one of ['none', 'adaptive_kl', 'linear'], got 'cosine'"),
        (["train", "BlueROV2Heavy-StationKeeping", "--ppo", "final_learning_rate=1"],
         "'final_learning_rate' must be between 0 and learning_rate (0.001), got 1.0"),
        (["train", "BlueROV2Heavy-StationKeeping", "--env", "reward.efort=1"], "unknown config key 'reward.efort'"),
        (["train", "BlueROV2Heavy-StationKeeping", "--ppo", "num_envs"], "--ppo expects KEY=VALUE"),
        (["eval", "/no/such/run"], "no such run directory or checkpoint"),
        (["train", "--resume", "/no/such/run"], "is not a run directory"),
        (["train", "BlueROV2Heavy-StationKeeping", "--wandb", "team/project"], "'team/project' is not a W&B project name"),
        (["train", "BlueROV2Heavy-StationKeeping", "--target-error", "-0.01"], "--target-error must be a positive"),
        (["train", "BlueROV2Heavy-StationKeeping", "--target-error", "nan"], "--target-error must be a positive"),
        (["eval", "BlueROV2Heavy-StationKeeping", "--checkpoint", "first"], "invalid choice: 'first'"),
        (["bench", "training", "BlueROV2Heavy-StationKeeping", "--seeds", "0"], "expected a positive int, got '0'"),
        (["bench", "training", "BlueROV2Heavy-StationKeeping", "--target-error", "-1"], "expected a positive float, got '-1'"),
        (["bench", "training", "BlueROV2Heavy-StationKeeping", "--target-error", "inf"], "expected a positive float, got 'inf'"),
        (["bench", "training", "BlueROV2Heavy-StationKeeping", "BlueROV2Heavy-Hover"], "unknown env 'BlueROV2Heavy-Hover'"),
        (["train", "BlueROV2Heavy-StationKeeping", "--algo", "a2c"], "invalid choice: 'a2c'"),
        (["train", "BlueROV2Heavy-StationKeeping", "--algo", "sac", "--ppo", "learning_rate=1e-3"], "PPO settings"),
        (["train", "BlueROV2Heavy-StationKeeping", "--algo", "sac", "--algo-opts", "unroll_length=5"], "unknown config key"),
        (["train", "BlueROV2Heavy-StationKeeping", "--algo", "sac", "--algo-opts", "min_replay_size=5000000"], "'min_replay_size'"),
        (["bench", "training", "BlueROV2Heavy-StationKeeping", "--algo", "sac", "--ppo", "seed=1"], "--ppo applies to --algo ppo"),
        (["train", "Remus100-Autopilot", "--ppo", "best_on=latest"], "'best_on' must be one of ['window_error', 'targets'], got 'latest'"),
        (["train", "BlueROV2Heavy-StationKeeping", "--ppo", "best_on=targets"],
         "'best_on' is 'targets' but BlueROV2Heavy-StationKeeping has no targets"),
    ],
)
def test_user_mistakes_exit_2_with_one_line_and_no_traceback(args, message):
    proc = marinejax(*args, timeout=120)
    assert proc.returncode == 2
    assert message in proc.stderr and "Traceback" not in proc.stderr
    if args[0] == "bench":
        assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


@pytest.mark.slow
def test_corrupt_checkpoint_is_reported(run_dir, tmp_path):
    run = tmp_path / "corrupt"
    shutil.copytree(run_dir, run)
    newest = sorted((run / "checkpoints").iterdir())[-1]
    for f in newest.rglob("*"):
        if f.is_file() and f.name != "ppo_network_config.json":
            f.write_bytes(b"garbage")
    proc = marinejax("eval", str(run), "--checkpoint", "latest", "--no-video", "--episodes", "2", timeout=300)
    assert proc.returncode == 2 and "could not be read" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.slow
def test_sac_learns_and_its_run_evaluates_exports_and_refuses_resume(tmp_path):
    """`--algo sac` for 70 k env steps of its tuned settings (about a minute here; the full 0.5 M
    reach a few mm, docs/results.md): the evaluation error falls far below the untrained policy's; the run
    directory is PPO's (checkpoints, best.json, the final evaluation); the export reproduces its
    deterministic policy; resuming is refused with the reason."""
    import jax

    from marinejax.export import load_numpy_policy
    from marinejax.train.checkpoints import load_policy

    run = tmp_path / "sac"
    proc = marinejax("train", "BlueROV2Heavy-StationKeeping", "--run-dir", str(run), "--algo", "sac", "--timesteps", "70000",
                     "--algo-opts", "num_evals=2", "--episodes", "4", "--no-video", timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "(SAC, 70,000 env steps" in proc.stdout
    config = json.loads((run / "config.json").read_text())
    assert config["algorithm"] == "sac" and "ppo" not in config
    records = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    untrained, trained = records[0]["eval/episode_window_error"], records[-1]["eval/episode_window_error"]
    assert records[-1]["step"] >= 70_000 and trained < 0.3 * untrained, (untrained, trained)
    checkpoints = sorted(p.name for p in (run / "checkpoints").iterdir())
    # Brax SAC saves after each evaluation but the first: one checkpoint with num_evals=2
    assert len(checkpoints) == 1 and int(checkpoints[0]) >= 70_000
    assert (run / "checkpoints" / checkpoints[0] / "sac_network_config.json").exists()
    assert json.loads((run / "summary.json").read_text())["evaluation"]["episodes"] == 4

    out = tmp_path / "policy.npz"
    assert marinejax("export", str(run), "--format", "npz", "--out", str(out)).returncode == 0
    _, env, policy, _ = load_policy(run)
    obs = np.random.default_rng(0).normal(size=(4, env.observation_size)).astype(np.float32)
    np.testing.assert_allclose(load_numpy_policy(out)(obs), np.asarray(jax.vmap(policy)(obs)), atol=1e-5)

    proc = marinejax("train", "--resume", str(run))  # Brax SAC cannot restore its checkpoints: said in one line
    assert proc.returncode == 2 and "a SAC run cannot be resumed" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_fixed_eval_episodes_leave_training_unchanged_and_evaluate_the_same_episodes(tmp_path):
    runs = {}
    for name, extra in (("new", []), ("fixed", ["--ppo", "fixed_eval_episodes=true"])):
        proc = marinejax("train", "BlueROV2Heavy-StationKeeping", "--run-dir", str(tmp_path / name), "--no-video", *TINY, *extra)
        assert proc.returncode == 0, proc.stderr[-3000:]
        runs[name] = [json.loads(line) for line in (tmp_path / name / "metrics.jsonl").read_text().splitlines()]

    def training(records):  # the losses, KL, rate and policy statistics; not the timings
        return [{k: v for k, v in r.items() if k.startswith("training/") and k not in ("training/walltime", "training/sps")}
                for r in records]

    assert training(runs["new"])[-1]["training/policy_loss"] and training(runs["new"]) == training(runs["fixed"])
    # the same policy at step 0 (the same seed), on other episodes: Brax's first evaluation's and ours differ
    assert runs["new"][0]["eval/episode_window_error"] != runs["fixed"][0]["eval/episode_window_error"]


@pytest.mark.slow
def test_a_best_checkpoint_on_targets_is_the_one_whose_worst_error_over_its_target_is_smallest(tmp_path):
    # the autopilot in 2 s episodes of two 1 s set-points (the window: the last 0.5 s of each)
    run = tmp_path / "ap"
    proc = marinejax("train", "Remus100-Autopilot", "--run-dir", str(run), "--no-video", *TINY, "--env", "segment_duration=1",
                     "--env", "settled=0.5", "--ppo", "best_on=targets")
    assert proc.returncode == 0, proc.stderr[-3000:]
    records = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    targets = {"eval/episode_window_error": 0.1, "eval/episode_window_heading_error_deg": 2.0, "eval/episode_window_speed_error": 0.05}
    scores = {r["step"]: max(r[key] / target for key, target in targets.items()) for r in records if r["step"] > 0}
    best = json.loads((run / "best.json").read_text())
    assert len(scores) == 2 and best["step"] == min(scores, key=scores.get) and best["score"] == pytest.approx(min(scores.values()))
    summary = json.loads((run / "summary.json").read_text())
    assert summary["evaluation"]["checkpoint_kind"] == "best (nearest to meeting every target during training)"
    assert summary["evaluation"]["checkpoint"].endswith(f"{best['step']:012d}")


@pytest.mark.slow
def test_target_error_stops_training_at_the_first_evaluation_that_meets_it(tmp_path):
    before = traced()
    # 2 evaluation envs: shapes no other run traced, which --no-compile-cache must not keep either
    proc = marinejax("train", "BlueROV2Heavy-StationKeeping", "--run-dir", str(tmp_path / "t"), "--target-error", "100",
                     "--no-video", "--no-compile-cache", *TINY, "--ppo", "num_eval_envs=2")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert traced() == before
    summary = json.loads((tmp_path / "t" / "summary.json").read_text())
    records = [json.loads(line) for line in (tmp_path / "t" / "metrics.jsonl").read_text().splitlines()]
    first = next(r for r in records if r["step"] > 0)
    assert summary["status"] == "target reached" and summary["time_to_target"]["step"] == first["step"]
    assert records[-1]["step"] == first["step"] < 1600  # stopped before the full budget
    assert "target 100.0 m met at" in proc.stdout


def test_a_checkpoint_chosen_on_targets_is_scored_by_its_error_furthest_over_its_target():
    from marinejax.train.curves import checkpoint_score

    autopilot = {"position_error": 0.1, "heading_error_deg": 2.0, "speed_error": 0.05}
    depth_only = {"eval/episode_window_error": 0.02, "eval/episode_window_heading_error_deg": 3.4,
                  "eval/episode_window_speed_error": 0.22}  # fine depth, speed traded for it
    all_three = {"eval/episode_window_error": 0.08, "eval/episode_window_heading_error_deg": 1.0,
                 "eval/episode_window_speed_error": 0.01}
    assert checkpoint_score(depth_only) == 0.02 < checkpoint_score(all_three) == 0.08  # the window error alone
    assert checkpoint_score(depth_only, autopilot) == pytest.approx(4.4)  # the speed: 0.22 / 0.05
    assert checkpoint_score(all_three, autopilot) == pytest.approx(0.8)  # the depth: 0.08 / 0.1
    assert checkpoint_score({"step": 0}, autopilot) is None and checkpoint_score({"step": 0}) is None


def test_latest_over_best_where_the_best_policy_makes_no_error():
    # a docking task's policies that dock every evaluation episode have error 0: no ratio to divide
    from marinejax.benchmarks.training import latest_over_best

    assert latest_over_best(0.2, 0.1) == pytest.approx(2.0)
    assert latest_over_best(0.0, 0.0) == 1.0 and latest_over_best(0.05, 0.0) == math.inf


def test_bench_aggregate_gives_the_speed_error_of_tasks_that_command_a_speed():
    # the torpedo autopilot's three targets are depth, heading and speed: all three over the seeds
    from marinejax.benchmarks.training import aggregate

    row = {"env": "Remus100-Autopilot", "seed": 0, "error_mean_m": 0.01, "heading_error_mean_deg": 1.0,
           "speed_error_mean": 0.02, "latest_over_best": 1.0, "success_rate": 1.0, "wall_time_s": 100.0, "target_steps": None}
    rows = [row, {**row, "seed": 1, "speed_error_mean": 0.06}, {**row, "seed": 2, "speed_error_mean": 0.03}]
    out = aggregate(rows, target=0.1)
    assert out["speed_error_median"] == pytest.approx(0.03) and out["speed_error_worst"] == pytest.approx(0.06)
    assert out["heading_error_deg_worst"] == 1.0
    # station keeping has no commanded speed: no speed figures rather than a made-up 0
    assert "speed_error_median" not in aggregate([{**r, "speed_error_mean": None} for r in rows], target=0.1)


@pytest.mark.slow
def test_bench_training_writes_results_over_seeds_and_reuses_finished_seeds(tmp_path):
    args = ["bench", "training", "BlueROV2Heavy-StationKeeping", "--seeds", "2", "--out-dir", str(tmp_path),
            "--timesteps", "1600", "--episodes", "4", "--target-error", "100",
            *[a for a in TINY if a not in ("--timesteps", "1600", "--episodes", "4")]]
    proc = marinejax(*args)
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads((tmp_path / "results.json").read_text())
    env = result["envs"][0]
    assert env["seeds"] == [0, 1] and len(env["errors_m"]) == 2
    assert env["error_worst_m"] == max(env["errors_m"]) and env["error_median_m"] <= env["error_worst_m"]
    assert env["reached_target_during_training"] == 2 and env["target_steps_median"] > 0
    for seed in result["seeds"]:  # the latest checkpoint on the best's episodes; the same numbers where it is the best
        summary = json.loads((Path(seed["run_dir"]) / "summary.json").read_text())
        assert seed["latest_checkpoint"] == str(sorted((Path(seed["run_dir"]) / "checkpoints").iterdir())[-1])
        assert summary["evaluation_latest"]["seed"] == summary["evaluation"]["seed"] == 12345
        assert (seed["latest_error_mean_m"] == seed["error_mean_m"]) == (seed["latest_checkpoint"] == seed["checkpoint"])
    ratios = [s["latest_error_mean_m"] / s["error_mean_m"] for s in result["seeds"]]
    assert env["latest_over_best_worst"] == pytest.approx(max(ratios))
    rows = (tmp_path / "results.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[0].startswith("env,seed,")
    assert (tmp_path / "BlueROV2Heavy-StationKeeping-seeds.png").stat().st_size > 10_000
    assert "median error" in proc.stdout
    again = marinejax(*args)
    assert again.returncode == 0 and again.stdout.count("finished earlier, reusing") == 2


@pytest.mark.slow
def test_bench_training_profile_splits_a_training_step_into_parts_that_sum_to_the_measured_step(tmp_path):
    tiny = [a for a in TINY if a not in ("--episodes", "4")]  # 1600 env steps, 3 evaluations
    # on one device (tests/train/test_profile.py: a recipe's several CPU devices, with the timings replaced)
    proc = marinejax("bench", "training", "BlueROV2Heavy-StationKeeping", "--profile", "--out-dir", str(tmp_path), *tiny)
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads((tmp_path / "profile-BlueROV2Heavy-StationKeeping.json").read_text())
    parts, shares = result["parts_s"], result["shares"]
    assert set(parts) == {"env", "policy", "normalizer", "loss_and_gradient", "optimizer", "other"}
    assert all(parts[name] > 0 for name in parts if name != "other")
    assert sum(parts.values()) == pytest.approx(result["training_step_s"], rel=1e-9)
    assert sum(shares.values()) == pytest.approx(1.0, rel=1e-9)
    assert result["env_steps_per_training_step"] == 8 * 2 * 5  # batch_size x num_minibatches x unroll_length
    assert result["training_env_steps_per_s"] == pytest.approx(80 / result["training_step_s"])
    recipe = result["recipe_s"]
    assert result["cpu_devices"] == 1 and result["training_step_on_cpu_devices_s"] == result["training_step_s"]
    assert recipe["training"] == pytest.approx(math.ceil(1600 / 80) * result["training_step_s"])
    assert recipe["compilation"] > 0
    assert sum(result["recipe_shares"].values()) == pytest.approx(1.0)
    assert "PPO loss and gradient" in proc.stdout and "training step, measured in ppo.train" in proc.stdout
    assert "CPU devices: training step" not in proc.stdout and "1 device(s)), projected" in proc.stdout
    refused = marinejax("bench", "training", "BlueROV2Heavy-StationKeeping", "--profile", "--algo", "sac", timeout=120)
    assert refused.returncode == 2 and "--profile profiles PPO" in refused.stderr


def test_key_values_take_json_style_booleans_and_python_literals():
    from marinejax.config import parse_key_values

    values = parse_key_values(["a=true", "b=False", "c=0.5", "d=(1, 2)", "e=ou", "f=FALSE"], "--env")
    assert values == {"a": True, "b": False, "c": 0.5, "d": (1, 2), "e": "ou", "f": False}


def test_list_shows_what_exists_and_eval_offers_every_controller():
    proc = marinejax("list")
    assert proc.returncode == 0, proc.stderr
    for expected in ("remus100_four_fin", "torpedo", "WaypointFollowing", "Remus100-CircleFollowingDisturbed",
                     "autopilot, los, terrain, avoid", "BlueROV2Heavy-StationKeeping", "open_water, pillars, rov_dock"):
        assert expected in proc.stdout
    from marinejax.cli import build_parser
    from marinejax.controllers import CONTROLLERS

    from marinejax.train.hyperparams import ALGORITHMS

    ev = build_parser()._subparsers._group_actions[0].choices["eval"]
    assert [a for a in ev._actions if a.dest == "controller"][0].choices == list(CONTROLLERS)
    tr = build_parser()._subparsers._group_actions[0].choices["train"]
    assert [a for a in tr._actions if a.dest == "algo"][0].choices == list(ALGORITHMS)
