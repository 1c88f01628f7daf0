"""Classical controllers: the pole placement, the inverse thruster curve, and closed-loop results on
the same episodes and statistics as a policy."""

import json
import subprocess
import sys

import jax.numpy as jnp
import numpy as np
import pytest

import marinejax
from marinejax.controllers import (LQRConfig, PIDConfig, TorpedoAutopilotConfig, hover_model, inverse_thrust, lqr_controller, lqr_gain,
                                   pid_controller, pid_gains, torpedo_autopilot)
from marinejax.errors import UserError
from marinejax.actuators.t200 import t200_thrust
from marinejax.statistics import rollout_controller, summarize


@pytest.fixture(scope="module")
def heavy():
    return marinejax.make("BlueROV2Heavy-StationKeeping")


def test_gains_place_a_triple_pole_at_minus_the_bandwidth(heavy):
    config = PIDConfig(translation_bandwidth=2.0, rotation_bandwidth=5.0)
    g = pid_gains(heavy, config)
    p = heavy.plant.nominal_params()
    mass = np.concatenate([np.full(3, float(p.mass)), np.asarray(p.inertia)]) + np.asarray(p.hydro.added_mass)
    damping = np.asarray(p.hydro.linear_damping)
    for axis, w in [(0, 2.0), (1, 2.0), (2, 2.0), (5, 5.0)]:  # axes with an integral: M s^3 + (D + kd) s^2 + kp s + ki
        roots = np.roots([mass[axis], damping[axis] + g.kd[axis], g.kp[axis], g.ki[axis]])
        np.testing.assert_allclose(roots.real, -w, rtol=2e-3, atol=2e-3 * w)
    for axis, w in [(3, 5.0), (4, 5.0)]:  # roll, pitch: PD, M s^2 + (D + kd) s + kp: √3 w, damping ratio √3/2
        roots = np.roots([mass[axis], damping[axis] + g.kd[axis], g.kp[axis]])
        np.testing.assert_allclose(np.abs(roots), np.sqrt(3) * w, rtol=1e-6)
        np.testing.assert_allclose(-roots.real / np.abs(roots), np.sqrt(3) / 2, rtol=1e-6)


def test_inverse_thrust_inverts_the_t200_curve(heavy):
    throttle = inverse_thrust(heavy.plant)
    p = heavy.plant.nominal_params().actuators[0]
    forces = jnp.linspace(-30.0, 35.0, 27)
    u = throttle(jnp.broadcast_to(forces[:, None], (27, heavy.vehicle.num_actuators)))
    back = t200_thrust(heavy.vehicle.sys.actuators[0].design.curve, u, p.voltage) * p.gain
    np.testing.assert_allclose(back, np.broadcast_to(forces[:, None], back.shape), atol=0.05)
    assert float(throttle(jnp.full(heavy.vehicle.num_actuators, 1e3))[0]) == 1.0
    assert float(throttle(jnp.full(heavy.vehicle.num_actuators, -1e3))[0]) == -1.0


def test_lqr_gain_stabilises_the_hover_model_of_both_vehicles():
    """The discrete closed loop of the design model is stable, and the 6-thruster BlueROV2's pitch
    (no thruster can make a pitch moment) is left to its restoring moment: no gain on pitch error."""
    for vehicle, n in (("BlueROV2Heavy", 8), ("BlueROV2", 6)):
        env = marinejax.make(f"{vehicle}-StationKeeping")
        k = lqr_gain(env, LQRConfig())
        assert k.shape == (n, 16) and np.all(np.isfinite(k))
        ad, bd = hover_model(env)
        assert np.abs(np.linalg.eigvals(ad - bd @ k)).max() < 1.0  # stable closed loop
        assert np.abs(np.linalg.eigvals(ad)).max() >= 1.0 - 1e-9  # the open loop is not (integrators, free position)
        alloc = np.asarray(env.vehicle.sys.actuators[0].design.allocation)
        pitch_moment = alloc[4] @ k  # pitch moment the feedback commands per unit of each state
        if vehicle == "BlueROV2":
            np.testing.assert_allclose(pitch_moment, 0.0, atol=1e-6)
        else:
            assert pitch_moment[4] > 1.0  # N m per rad of pitch


# Each controller holds station and tracks a slow circle (0.2-0.5 m/s) on the nonlinear simulator;
# the bounds are about twice what they reach (docs/controllers.md), on other episodes than the tuning's.
@pytest.mark.parametrize("env_name, controller, median_below", [
    ("BlueROV2Heavy-StationKeeping", pid_controller, 0.002),
    pytest.param("BlueROV2Heavy-StationKeeping", lqr_controller, 0.002, marks=pytest.mark.slow),
    pytest.param("BlueROV2-CircleTracking", pid_controller, 0.01, marks=pytest.mark.slow),
    ("BlueROV2Heavy-CircleTracking", lqr_controller, 0.01),
    pytest.param("BlueROV2-StationKeepingDisturbed", pid_controller, 0.015, marks=pytest.mark.slow),
    pytest.param("BlueROV2-StationKeepingDisturbed", lqr_controller, 0.01, marks=pytest.mark.slow),
])
def test_controllers_reach_the_target_on_the_evaluation_statistic(env_name, controller, median_below):
    env = marinejax.make(env_name)
    config = PIDConfig(3.0, 6.0) if controller is pid_controller else LQRConfig(position_scale=0.02)
    stats = summarize(env, rollout_controller(env, controller(env, config), episodes=8, seed=12345))
    assert stats["position_error_median_m"] < median_below, stats
    assert stats["terminated_episodes"] == 0


def test_torpedo_autopilot_holds_depth_and_heading():
    """The reference's autopilot (depth gain 0.8 rad/m, the tuned value) on the REMUS 100's autopilot
    task, other episodes than the tuning's: most set-points held to centimetres, heading within
    degrees (the slow episodes, 0.5 m/s, have little fin authority: the mean is larger)."""
    env = marinejax.make("Remus100-Autopilot")
    stats = summarize(env, rollout_controller(env, torpedo_autopilot(env, TorpedoAutopilotConfig(depth_gain=0.8)), episodes=16, seed=12345))
    assert stats["position_error_median_m"] < 0.05 and stats["heading_error_mean_deg"] < 10, stats
    assert stats["terminated_episodes"] == 0
    with pytest.raises(UserError, match="needs the autopilot or a path-following task of a vehicle with fins and a propeller"):
        torpedo_autopilot(marinejax.make("BlueROV2Heavy-StationKeeping"))


def test_pid_reads_the_sensor_observation_too():
    env = marinejax.make("BlueROV2Heavy-StationKeeping", observation_mode="sensors")
    stats = summarize(env, rollout_controller(env, pid_controller(env, PIDConfig(3.0, 6.0)), episodes=4, seed=3))
    assert 0.002 < stats["position_error_median_m"] < 0.1  # worse than with the exact state, still holds station


def test_pid_refuses_wrench_actions():
    env = marinejax.make("BlueROV2Heavy-StationKeeping", action_mode="wrench")
    with pytest.raises(UserError, match="action_mode"):
        pid_controller(env)
    with pytest.raises(UserError, match="action_mode"):
        lqr_controller(env)
    with pytest.raises(UserError, match="translation_bandwidth"):
        PIDConfig(translation_bandwidth=-1.0)


@pytest.mark.slow
def test_eval_runs_a_tuned_controller_from_the_command_line(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "marinejax.cli", "eval", "BlueROV2Heavy-StationKeeping", "--controller", "pid",
         "--episodes", "8", "--no-video", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=900,
    )
    assert proc.returncode == 0, proc.stderr
    assert "PID tuning: translation bandwidth (rad/s; rotation twice) 1:" in proc.stdout and "controller: pid" in proc.stdout
    result = json.loads((tmp_path / "eval.json").read_text())
    assert result["controller"] == "pid" and result["position_error_median_m"] < 0.005
    tuning = result["tuning"]["mean_error_m"]
    assert result["config"]["translation_bandwidth"] == float(min(tuning, key=tuning.get))
    bad = subprocess.run([sys.executable, "-m", "marinejax.cli", "eval", "BlueROV2Heavy-StationKeeping", "--controller", "mpc"],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "mpc" in bad.stderr
