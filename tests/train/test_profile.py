"""`bench training --profile`'s arithmetic (marinejax.benchmarks.profile) with its timings replaced:
which measurement each figure and the projected recipe come from, without compiling a training
(the slow CLI test times a real one)."""

import math

import jax
import pytest

from marinejax.benchmarks import profile as prof

PARTS = {"env": 0.04, "policy": 0.002, "normalizer": 0.001, "loss_and_gradient": 0.05, "optimizer": 0.007}
MEASURED = {1: {"training_step": 0.2, "evaluation": 0.5, "compilation": 30.0},
            2: {"training_step": 0.125, "evaluation": 0.4, "compilation": 40.0}}


@pytest.mark.parametrize("local_devices", [2, 1])
def test_a_recipe_on_two_cpu_devices_is_projected_from_the_step_measured_on_them(monkeypatch, local_devices):
    calls = []

    def measured(env, agent, module, steps_per_training_step, step_estimate, devices=1):
        calls.append((devices, step_estimate))
        return MEASURED[devices]

    monkeypatch.setattr(prof, "_parts", lambda env, agent, network_factory: dict(PARTS))
    monkeypatch.setattr(prof, "_measured", measured)
    monkeypatch.setattr(jax, "local_device_count", lambda: local_devices)
    result = prof.profile("BlueROV2Heavy-StationKeeping", {"cpu_devices": 2, "num_timesteps": 1_000_000, "num_evals": 10})

    steps = result["env_steps_per_training_step"]
    assert steps == 256 * 10 * 4  # the recipe's batch_size x num_minibatches x unroll_length
    used = MEASURED[local_devices]  # a host with one device measures, and projects, on that one
    assert calls == ([(1, pytest.approx(sum(PARTS.values()))), (2, pytest.approx(0.1))] if local_devices == 2
                     else [(1, pytest.approx(sum(PARTS.values())))])
    assert result["cpu_devices"] == local_devices
    # the parts and "other" are one device's, summing to the step measured on one device
    assert result["training_step_s"] == 0.2 and result["parts_s"]["other"] == pytest.approx(0.2 - sum(PARTS.values()))
    assert sum(result["shares"].values()) == pytest.approx(1.0)
    assert result["evaluation_s"] == 0.5
    assert result["training_step_on_cpu_devices_s"] == used["training_step"]
    assert result["cpu_devices_speedup"] == pytest.approx(0.2 / used["training_step"])
    assert result["recipe_s"] == pytest.approx({"training": math.ceil(1_000_000 / steps) * used["training_step"],
                                                "evaluations": 10 * used["evaluation"], "compilation": used["compilation"]})
    report = prof.report(result)
    assert ("the recipe's 2 CPU devices: training step 0.1250 s, 1.60× the one device's above" in report) == (local_devices == 2)
    assert f"{local_devices} device(s)), projected: {sum(result['recipe_s'].values()):.0f} s" in report
