"""Training really learns, and the shipped policy reproduces its figure in docs/results.md (SAC's learning:
`tests/train/test_cli.py`, with its run directory)."""

import json
from pathlib import Path

import pytest

from marinejax.train.checkpoints import shipped_policies
from marinejax.train.evaluate import evaluate_run


# CI checks one shipped policy per task family and vehicle kind (each costs a compilation, about 20 s);
# `pytest -m exhaustive` checks the others, as before shipping a policy or changing an env.
_REPRESENTATIVE = {"BlueROV2Heavy-StationKeeping", "BlueROV2-StationKeepingDisturbed", "BlueROV2Heavy-LemniscateTracking",
                   "Remus100-WaypointFollowing", "Remus100-Autopilot"}


@pytest.mark.slow
@pytest.mark.parametrize("env_name", [name if name in _REPRESENTATIVE else pytest.param(name, marks=pytest.mark.exhaustive)
                                      for name in sorted(shipped_policies())])
def test_shipped_policy_reproduces_its_recorded_evaluation(env_name, tmp_path):
    """Every shipped policy (both ROVs, four tasks each, and their disturbed variants; the REMUS's
    waypoint following and autopilot)."""
    run = shipped_policies()[env_name]
    recorded = json.loads((run / "eval.json").read_text())
    result = evaluate_run(env_name, out_dir=tmp_path, episodes=recorded["episodes"], seed=recorded["seed"], video=False)
    assert result["position_error_mean_m"] == pytest.approx(recorded["position_error_mean_m"], abs=1e-3)
    assert result["success_rate"] == pytest.approx(recorded["success_rate"], abs=0.05)
    assert Path(result["plot"]).exists()


@pytest.mark.slow
def test_tuned_station_keeping_recipe_lands_on_a_held_out_seed(tmp_path):
    """`marinejax train BlueROV2Heavy-StationKeeping --seed 5 --target-error 0.01` from scratch, on a
    seed outside docs/results.md's 0-4: it stops at the first evaluation within 1 cm (the seeds there
    reach 2 cm after 3.2-8.3 M of the 12 M steps), and the 64 evaluation episodes of that policy
    keep the pose: within 2 cm and 2° mean error over the last second, every one a success (position
    and heading). One seed, stopped early, keeps CI's time; the whole budget on seeds 0-4 is
    docs/results.md's benchmark."""
    from marinejax.benchmarks.training import run_seed

    row = run_seed("BlueROV2Heavy-StationKeeping", 5, tmp_path / "run", {}, {}, 0.01, 64, log=lambda _: None, stop_at_target=True)
    assert row["target_steps"] is not None and row["env_steps"] < 12_000_000, row
    assert row["error_mean_m"] <= 0.02 and row["heading_error_mean_deg"] <= 2.0, row
    assert row["success_rate"] == 1.0, row


@pytest.mark.slow
@pytest.mark.parametrize("vehicle, mean_ratio, p95_ratio", [("BlueROV2Heavy", 0.5, 0.5), ("BlueROV2", 0.95, 0.9)])
def test_disturbance_trained_policy_beats_the_nominal_one_under_disturbance(vehicle, mean_ratio, p95_ratio, tmp_path):
    """Both shipped station-keeping policies of a vehicle on the same 64 disturbed episodes (new physics,
    OU current, constant force and torque each): the one trained under disturbance holds station
    better: Heavy 27.6 / 76.9 mm mean / p95 against 5.9 / 15.0 mm. The BlueROV2 (no pitch control)
    gains less, mostly in the tail: nominal policy 27.3 / 19.7 / 70.8 mm mean / median / p95,
    disturbance policy 23.9 / 20.5 / 56.0 mm."""
    disturbed = {"randomization.enabled": True, "current.mode": "ou", "disturbance.enabled": True}
    nominal = evaluate_run(f"{vehicle}-StationKeeping", out_dir=tmp_path / "n", env_overrides=disturbed, video=False)
    robust = evaluate_run(f"{vehicle}-StationKeepingDisturbed", out_dir=tmp_path / "d", video=False)
    assert robust["env_overrides"] == {} and nominal["seed"] == robust["seed"]
    assert robust["position_error_median_m"] <= 0.03 and robust["position_error_p95_m"] <= 0.06
    assert robust["position_error_mean_m"] < mean_ratio * nominal["position_error_mean_m"], (robust, nominal)
    assert robust["position_error_p95_m"] < p95_ratio * nominal["position_error_p95_m"], (robust, nominal)


def test_every_task_of_both_vehicles_has_a_shipped_policy():
    tasks = ["StationKeeping", "CircleTracking", "HelixTracking", "LemniscateTracking"]
    expected = {f"{v}-{t}" for v in ("BlueROV2", "BlueROV2Heavy") for t in tasks} | {f"{v}-StationKeepingDisturbed" for v in ("BlueROV2", "BlueROV2Heavy")}
    assert expected <= set(shipped_policies())
