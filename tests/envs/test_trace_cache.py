"""The on-disk cache of the training env's traced reset and step (`envs/trace_cache.py`)."""

import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from brax.envs.base import Env

import marinejax.envs as E
from marinejax.envs import trace_cache
from marinejax.envs.trace_cache import env_fingerprint
from marinejax.errors import UserError

BATCH, STEPS, EPISODE = 2, 3, 2  # an episode ends (and the wrapper resets) inside the rollout


def rollout(batched, actions):
    """Reset and STEPS steps of a batched env, jitted as one function; the state after each."""

    def run(keys):
        state = batched.reset(keys)

        def body(s, a):
            s = batched.step(s, a)
            return s, s

        return jax.lax.scan(body, state, actions)[1]

    return jax.jit(run)(jax.random.split(jax.random.PRNGKey(3), BATCH))


@pytest.fixture(scope="module")
def env():
    return E.make("BlueROV2Heavy-StationKeeping")


@pytest.fixture(scope="module")
def actions(env):
    return 0.4 * jnp.sin(jnp.arange(STEPS * BATCH * env.action_size, dtype=jnp.float32)).reshape(STEPS, BATCH, -1)


@pytest.fixture(scope="module")
def reference(env, actions):
    return rollout(E.wrap_for_training(env, EPISODE), actions)


@pytest.fixture(scope="module")
def cache(env, actions, tmp_path_factory):
    folder = tmp_path_factory.mktemp("traced")
    return folder, rollout(E.wrap_for_training(env, EPISODE, trace_cache=folder), actions)


def assert_same(a, b):
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_first_use_writes_one_artifact_per_function_and_changes_no_number(cache, reference):
    folder, states = cache
    assert sorted(p.name.split("-")[0] for p in folder.iterdir()) == ["reset", "step"]
    assert_same(states, reference)
    assert np.all(np.isfinite(np.asarray(states.obs))) and float(jnp.abs(states.obs[-1] - states.obs[0]).max()) > 0
    assert [int(t[0]) for t in states.info["truncation"]] == [0, 1, 0]


def test_a_new_wrapper_loads_the_artifacts_instead_of_tracing(cache, reference, env, actions, monkeypatch):
    folder, _ = cache
    files = {p: p.stat().st_mtime_ns for p in folder.iterdir()}

    def no_export(*args, **kwargs):
        raise AssertionError("exported again although the artifact was on disk")

    monkeypatch.setattr(trace_cache.export, "export", no_export)
    assert_same(rollout(E.wrap_for_training(env, EPISODE, trace_cache=folder), actions), reference)
    assert {p: p.stat().st_mtime_ns for p in folder.iterdir()} == files


def test_another_batch_size_gets_its_own_artifact_and_a_damaged_one_is_rewritten(cache, env, tmp_path):
    folder, _ = cache
    keys = jax.random.split(jax.random.PRNGKey(0), 3)
    shape = jax.eval_shape(E.wrap_for_training(env, EPISODE, trace_cache=tmp_path).reset, keys)
    (artifact,) = tmp_path.iterdir()
    assert artifact.name not in {p.name for p in folder.iterdir()}
    artifact.write_bytes(b"not an export")
    again = jax.eval_shape(E.wrap_for_training(env, EPISODE, trace_cache=tmp_path).reset, keys)
    assert jax.tree.structure(again) == jax.tree.structure(shape) and artifact.stat().st_size > 1000


def test_the_key_follows_the_config_the_task_the_vehicle_and_the_wrappers(env):
    assert env_fingerprint(E.make("BlueROV2Heavy-StationKeeping")) == env_fingerprint(env)
    others = [
        E.make("BlueROV2Heavy-StationKeeping", current={"mode": "constant"}),  # config
        E.make("BlueROV2-StationKeeping"),  # vehicle
    ]
    circle, helix = E.make("BlueROV2Heavy-CircleTracking"), E.make("BlueROV2Heavy-HelixTracking")
    assert circle.config == helix.config  # the same config: only the task's `kind` differs
    wrapped = [E.wrap_for_training(env, 10), E.wrap_for_training(env, 20)]  # the episode length
    prints = {env_fingerprint(e) for e in [env, *others, circle, helix, *wrapped]}
    assert len(prints) == 7


class NotMarine(Env):
    reset = step = lambda self, *args: None
    observation_size = action_size = 1
    backend = "mjx"


def test_without_a_folder_nothing_is_written_and_other_envs_are_refused(env, tmp_path):
    wrapped = E.wrap_for_training(env, episode_length=4)
    jax.eval_shape(wrapped.reset, jax.random.split(jax.random.PRNGKey(0), 2))
    assert not any(tmp_path.iterdir())
    with pytest.raises(UserError, match="the trace cache needs a marinejax env .* got NotMarine"):
        jax.eval_shape(E.wrap_for_training(NotMarine(), trace_cache=tmp_path).reset, jax.random.split(jax.random.PRNGKey(0), 2))


FRESH_PROCESS = """
import sys, jax, jax.numpy as jnp, numpy as np
import marinejax.envs as E
env = E.make("BlueROV2Heavy-StationKeeping")
w = E.wrap_for_training(env, {episode}, trace_cache=sys.argv[1])
s = w.reset(jax.random.split(jax.random.PRNGKey(3), {batch}))
s = jax.jit(w.step)(s, jnp.full(({batch}, env.action_size), 0.4))
np.save(sys.argv[2], np.asarray(s.obs))
"""


@pytest.mark.slow
def test_a_fresh_process_runs_the_loaded_artifacts(cache, env, tmp_path):
    # A process that never lowered a LAPACK op must still run the Cholesky solve inside the loaded
    # step (jaxlib loads its LAPACK kernels lazily; without `_load_lapack` this segfaults).
    folder = tmp_path / "traced"
    script = FRESH_PROCESS.format(batch=BATCH, episode=EPISODE)
    outputs, written = [], []
    for i in range(2):  # the first process exports, the second loads
        out = tmp_path / f"obs{i}.npy"
        proc = subprocess.run([sys.executable, "-c", script, str(folder), str(out)], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-3000:]
        outputs.append(np.load(out))
        written.append({p.name: p.stat().st_mtime_ns for p in folder.iterdir()})
    assert len(written[0]) == 2 and written[1] == written[0]
    np.testing.assert_array_equal(outputs[0], outputs[1])
    w = E.wrap_for_training(env, EPISODE)
    s = w.reset(jax.random.split(jax.random.PRNGKey(3), BATCH))
    np.testing.assert_array_equal(outputs[0], np.asarray(jax.jit(w.step)(s, jnp.full((BATCH, env.action_size), 0.4)).obs))
