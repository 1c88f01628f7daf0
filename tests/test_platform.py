"""Start-up and platform: silent import, the jax compatibility shim, plain CLI output off a terminal."""

import io
import re
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from marinejax import _compat


def test_import_prints_nothing():
    proc = subprocess.run([sys.executable, "-c", "import marinejax"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "" and proc.stderr == ""


def test_import_leaves_jax_uninitialised_so_that_processes_can_still_join_jax_distributed():
    # jax.distributed.initialize must come before JAX's backend starts; an array made at import
    # time (a module constant) would start it.
    code = ("import socket, jax, marinejax, marinejax.cli, marinejax.train.runner\n"
            "s = socket.socket(); s.bind(('127.0.0.1', 0)); port = s.getsockname()[1]; s.close()\n"
            "jax.distributed.initialize(f'127.0.0.1:{port}', num_processes=1, process_id=0)\n"
            "print(jax.process_count(), marinejax.vehicle.mjx_device() == jax.local_devices()[0])")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split()[-2:] == ["1", "True"]


def test_device_put_replicated_shim_stacks_one_copy_per_device_for_pmap():
    devices = jax.local_devices()
    tree = {"w": np.arange(6.0).reshape(2, 3), "n": np.int32(7), "nested": (jnp.ones(4),)}
    out = _compat.device_put_replicated(tree, devices)
    assert out["w"].shape == (len(devices), 2, 3) and out["n"].shape == (len(devices),)
    np.testing.assert_array_equal(out["w"][0], tree["w"])
    assert out["n"].dtype == np.int32 and out["nested"][0].shape == (len(devices), 4)
    summed = jax.pmap(lambda t: t["w"].sum() * t["n"])(out)
    np.testing.assert_allclose(summed, np.full(len(devices), 15.0 * 7))
    with pytest.raises(ValueError, match="at least one device"):
        _compat.device_put_replicated(tree, [])


def test_shim_is_present_after_import_and_installed_only_where_missing():
    import marinejax  # noqa: F401

    assert callable(jax.device_put_replicated)
    assert _compat.install() is False  # present now (jax's own before 0.10, else the shim): nothing to add
    native = sys.modules["jax"].__dict__.get("device_put_replicated") is not _compat.device_put_replicated
    assert native == (tuple(int(p) for p in jax.__version__.split(".")[:2]) < (0, 10))


PLAIN_LINE = re.compile(
    r"^eval step=\d+/\d+ elapsed_s=\d+\.\d steps_per_s=(\d+|-) return=(-?\d+\.\d\d|-) error_m=(\d+\.\d{4}|-) "
    r"best_error_m=(\d+\.\d{4}|-)$"
)


def test_training_progress_prints_one_plain_line_per_evaluation_off_a_terminal():
    from marinejax.console import make_console
    from marinejax.train.hyperparams import tuned_config
    from marinejax.train.progress import TrainingProgress

    out = io.StringIO()
    console = make_console(out)
    assert not console.is_terminal
    records = [
        {"step": 0, "elapsed": 12.5, "eval/episode_reward": -40.0, "eval/episode_window_error": 1.6},
        {"step": 634_880, "elapsed": 44.25, "eval/episode_reward": -12.345, "eval/episode_window_error": 0.0123},
        {"step": 1_269_760, "elapsed": 65.0, "eval/episode_reward": -13.0, "eval/episode_window_error": 0.05},
    ]
    with TrainingProgress(console, tuned_config("BlueROV2Heavy-StationKeeping")) as progress:
        for record in records:
            progress.update(record)
        console.print("run directory: /" + "very-long-directory-name/" * 12 + "run")
    lines = out.getvalue().splitlines()
    assert len(lines) == 4 and all(PLAIN_LINE.match(line) for line in lines[:3]), lines
    assert lines[1] == ("eval step=634880/12000000 elapsed_s=44.2 steps_per_s=19996 return=-12.35 error_m=0.0123 "
                        "best_error_m=0.0123")
    assert lines[2].endswith("error_m=0.0500 best_error_m=0.0123")
    assert lines[3].endswith("very-long-directory-name/run") and "\x1b" not in out.getvalue()


def test_cli_reports_user_errors_in_one_line_and_lets_bugs_raise(monkeypatch, capsys):
    from marinejax import cli, validation
    from marinejax.errors import MissingFileError, UserError

    assert cli.main(["validate", "--vehicle", "submarine", "--no-compile-cache"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown vehicle 'submarine'" in err[0] and "bluerov2_heavy" in err[0]

    def bug(*args, **kwargs):
        raise ValueError("an internal bug")

    monkeypatch.setattr(validation, "print_validation", bug)
    with pytest.raises(ValueError, match="an internal bug"):  # not turned into a one-line user error
        cli.main(["validate", "--no-compile-cache"])
    assert issubclass(UserError, ValueError) and issubclass(MissingFileError, FileNotFoundError)
