"""Export of trained policies: NumPy weights and ONNX reproduce the JAX policy; the NumPy policy closes
the loop outside any jitted code and reaches the evaluation's error."""

import json
import subprocess
import sys

import jax
import numpy as np
import pytest

import marinejax

from marinejax.control import policy_controller, rollout
from marinejax.export import export_policy, load_numpy_policy
from marinejax.train.checkpoints import load_policy
from marinejax.statistics import rollout_policy

ENV = "BlueROV2-StationKeeping"  # a shipped policy


@pytest.fixture(scope="module")
def shipped():
    config, env, policy, ckpt = load_policy(ENV)
    return env, policy


@pytest.fixture(scope="module")
def observations(shipped):
    """1,600 observations recorded along 16 episodes of the policy (100 steps each)."""
    env, policy = shipped
    keys = jax.random.split(jax.random.PRNGKey(3), 16)
    _, obs = rollout(env, policy_controller(policy), keys, 100, lambda s: s.obs)
    return np.asarray(obs).reshape(-1, env.observation_size)


def test_numpy_export_matches_the_jax_policy(tmp_path, shipped, observations):
    env, policy = shipped
    path = export_policy(ENV, "npz", tmp_path / "policy.npz")
    numpy_policy = load_numpy_policy(path)
    expected = np.asarray(jax.jit(jax.vmap(policy))(observations))
    assert observations.shape[0] >= 1000
    np.testing.assert_allclose(numpy_policy(observations), expected, atol=1e-5)
    np.testing.assert_allclose(numpy_policy(observations[7]), expected[7], atol=1e-5)  # one observation
    meta = numpy_policy.metadata
    assert meta["env"] == ENV and meta["observation_size"] == env.observation_size and meta["action_size"] == 6
    assert meta["control_dt_s"] == 0.05
    assert meta["observation_layout"][0] == {"name": "position_error", "start": 0, "stop": 3, "unit": "m", "frame": "body",
                                             "meaning": "target (or the path's closest point) minus position"}
    assert "thruster" in meta["action"] and meta["observation_mode"].startswith("state")


def test_onnx_export_matches_the_jax_policy(tmp_path, shipped, observations):
    ort = pytest.importorskip("onnxruntime")
    import onnx

    env, policy = shipped
    path = export_policy(ENV, "onnx", tmp_path / "policy.onnx")
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    (action,) = session.run(["action"], {"observation": observations.astype(np.float32)})
    expected = np.asarray(jax.jit(jax.vmap(policy))(observations))
    np.testing.assert_allclose(action, expected, atol=1e-5)
    props = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
    assert json.loads(props["marinejax"])["env"] == ENV


def test_numpy_policy_closes_the_loop_outside_jit(tmp_path, shipped):
    """The exported NumPy policy drives the simulator step by step from Python, with no JAX in the
    policy, for whole episodes: the same error as `marinejax eval` on the same episodes."""
    env, policy = shipped
    numpy_policy = load_numpy_policy(export_policy(ENV, "npz", tmp_path / "policy.npz"))
    episodes = 2
    reference = rollout_policy(env, policy, episodes, seed=5)
    reset, step = jax.jit(env.reset), jax.jit(env.step)
    keys = jax.random.split(jax.random.PRNGKey(5), episodes)
    errors = np.zeros((episodes, env.config.episode_length))
    for e in range(episodes):
        state = reset(keys[e])
        for t in range(env.config.episode_length):
            state = step(state, numpy_policy(np.asarray(state.obs)))
            errors[e, t] = float(state.metrics["position_error"])
    window = np.asarray(env.error_window(reference["time"]))
    ours = errors[:, window].mean(axis=1)
    theirs = reference["error"][:, window].mean(axis=1)
    assert np.all(ours < 0.02)
    np.testing.assert_allclose(ours, theirs, atol=2e-4)


@pytest.mark.parametrize("args, message", [
    (["--format", "tflite"], "invalid choice: 'tflite'"),
    (["/no/such/run", "--format", "npz"], "no such run directory or checkpoint: /no/such/run"),
    (["--format", "npz", "--out", "/proc/marinejax/policy.npz"], "cannot write /proc/marinejax/policy.npz"),
])
def test_bad_export_input_is_one_line(tmp_path, args, message):
    argv = ["export", ENV, *args] if args[0].startswith("--") else ["export", *args]
    proc = subprocess.run([sys.executable, "-m", "marinejax.cli", *argv], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode != 0
    assert message in proc.stderr and "Traceback" not in proc.stderr


def test_run_without_checkpoint_is_a_user_error(tmp_path):
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "config.json").write_text("{}")
    proc = subprocess.run([sys.executable, "-m", "marinejax.cli", "export", str(run), "--format", "npz"], capture_output=True,
                          text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 2 and "has no complete checkpoint" in proc.stderr and "Traceback" not in proc.stderr


def test_export_metadata_names_the_sensor_mode_and_its_settings():
    from marinejax.export import _observation_mode

    exact = marinejax.make(ENV).config
    assert _observation_mode(exact).startswith("state")
    sensed = marinejax.make(ENV, observation_mode="sensors", **{"sensors.latency.action": 2}).config
    meta = json.loads(json.dumps(_observation_mode(sensed)))  # JSON-serialisable, as written into the files
    assert meta["mode"].startswith("sensors") and meta["sensors"]["latency"]["action"] == 2
    assert meta["sensors"]["dvl"]["rate_hz"] == 10.0 and "position_fix" in meta["sensors"]
