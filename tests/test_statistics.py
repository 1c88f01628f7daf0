"""The evaluation statistics on hand-made episodes (no simulation)."""

import numpy as np
import pytest

import marinejax
from marinejax.statistics import summarize


def _episodes(env, position_m, heading_deg):
    """One episode per entry, each holding its position error (m) and heading error (°) throughout."""
    steps = env.config.episode_length
    full = lambda values: np.repeat(np.asarray(values, float)[:, None], steps, axis=1)  # noqa: E731
    return {"time": env.config.control_dt * np.arange(1, steps + 1), "error": full(position_m),
            "heading_error_deg": full(heading_deg), "done": np.zeros((len(position_m), steps))}


def test_station_keeping_succeeds_only_with_both_the_position_and_the_heading():
    env = marinejax.make("BlueROV2Heavy-StationKeeping")
    assert env.success_threshold_m == 0.1 and env.success_heading_deg == 5.0
    stats = summarize(env, _episodes(env, [0.01, 0.01, 0.2, 0.01], [1.0, 6.0, 1.0, 4.9]))
    assert stats["success_rate"] == 0.5 and stats["success_heading_deg"] == 5.0
    assert stats["heading_error_mean_deg"] == pytest.approx(3.225)


def test_a_task_without_a_heading_bound_succeeds_on_the_position_alone():
    env = marinejax.make("BlueROV2Heavy-CircleTracking")
    assert env.success_heading_deg is None
    stats = summarize(env, _episodes(env, [0.01, 0.2], [90.0, 0.0]))
    assert stats["success_rate"] == 0.5 and stats["success_heading_deg"] is None


def test_rov_docking_succeeds_when_docked_at_the_end_whatever_its_position_error():
    env = marinejax.make("BlueROV2Heavy-Docking")
    assert env.success_flag == "docked"
    result = _episodes(env, [0.08, 0.01, 0.01], [0.0, 0.0, 0.0])
    steps = env.config.episode_length
    docked = np.zeros((3, steps))
    docked[0, -30:] = 1.0  # docked 8 cm before the landing point (inside the station): a success
    docked[2, 100:-1] = 1.0  # docked, then out on the last step: not
    other = np.zeros((3, steps))
    result.update(docked=docked, impact_force=other, lateral_error=other)
    stats = summarize(env, result)
    assert stats["success_rate"] == pytest.approx(1 / 3) and stats["success_flag"] == "docked"
