"""Trained policies out of JAX, for the vehicle's computer: NumPy weights with a dependency-free
inference function, or an ONNX model (for onnxruntime, TensorRT, ...).

    marinejax export RUN_OR_ENV --format npz|onnx [--out PATH]

    from marinejax.export import load_numpy_policy       # needs only NumPy
    policy = load_numpy_policy("policy.npz")
    action = policy(observation)                           # (obs,) or (B, obs) float -> (action,) or (B, action)

The exported function is the deterministic policy of the checkpoint (PPO or SAC): the observation
normalized with the running statistics of training, (obs − mean) / std, an MLP with swish hidden
layers, and tanh of the mean half of the last layer. A mirror-symmetric PPO policy
(`ppo.Config.mirror_symmetric`) averages that mean with the reflected mean for the reflected
observation (`envs.symmetry.Mirror`; its signed permutations travel in the files). Both files carry the same metadata (JSON in
`metadata` of the npz, in the ONNX model's metadata_props): env, checkpoint, control period,
observation size and layout (`MarineEnv.observation_layout`: per field its slice, unit and frame), observation mode, action size and meaning
(thruster order), frames and units.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

from marinejax._version import __version__
from marinejax.errors import UserError

FORMATS = ("npz", "onnx")


@dataclasses.dataclass(frozen=True)
class PolicyWeights:
    """A deterministic policy (PPO or SAC) as plain arrays (float32)."""

    mean: np.ndarray  # (obs,) observation mean of training
    std: np.ndarray  # (obs,) observation standard deviation of training
    kernels: tuple[np.ndarray, ...]  # (in, out) per layer
    biases: tuple[np.ndarray, ...]  # (out,) per layer
    action_size: int
    metadata: dict[str, Any]
    # A mirror-symmetric policy's reflections (`envs.symmetry.Mirror`): obs_perm, obs_sign,
    # action_perm, action_sign; None for a plain policy.
    mirror: dict[str, np.ndarray] | None = None

    def _mean(self, observation: np.ndarray) -> np.ndarray:
        x = (observation - self.mean) / self.std
        for i, (w, b) in enumerate(zip(self.kernels, self.biases)):
            x = x @ w + b
            if i < len(self.kernels) - 1:
                x = x / (1.0 + np.exp(-x))  # swish: x · sigmoid(x)
        return x[..., : self.action_size]

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        """Action(s) in [−1, 1] for observation(s) (obs,) or (B, obs), NumPy only."""
        obs = np.asarray(observation, dtype=np.float32)
        loc = self._mean(obs)
        if self.mirror is not None:
            m = self.mirror
            image = self._mean(obs[..., m["obs_perm"]] * m["obs_sign"])
            loc = 0.5 * (loc + image[..., m["action_perm"]] * m["action_sign"])
        return np.tanh(loc)


def _observation_mode(config) -> str | dict:
    """What the policy was trained to observe: the exact state, or the sensor suite and its settings."""
    if config.observation_mode == "state":
        return "state: the exact simulator state (no sensor model)"
    import dataclasses

    return {
        "mode": "sensors: the state estimated by marinejax.plant.estimator (complementary filter) from the IMU, "
                "depth sensor, attitude estimate, DVL and position fix of marinejax.plant.sensors; the observation "
                "is latency.observation control steps old and actions reach the thrusters latency.action steps late",
        "sensors": dataclasses.asdict(config.sensors),
    }


def policy_weights(path: Path | str, which: str = "best") -> PolicyWeights:
    """The policy of a run directory, checkpoint or shipped policy (env name), with its metadata."""
    import jax

    from marinejax.train.checkpoints import load_params

    config, env, params, ckpt = load_params(path, None, which)
    if not isinstance(env.observation_size, int):
        raise UserError(f"{config.env} was trained with a dict observation; export supports the flat 'state' observation only")
    normalizer, policy = params[0], params[1]["params"]
    layers = sorted(policy, key=lambda name: int(name.split("_")[-1]))
    if not config.agent.normalize_observations:
        mean, std = np.zeros(env.observation_size, np.float32), np.ones(env.observation_size, np.float32)
    else:
        mean, std = np.asarray(normalizer.mean, np.float32), np.asarray(normalizer.std, np.float32)
    c = env.config
    action = (env.vehicle.describe_action() if c.action_mode == "thrusters"
              else f"body wrench [Fx, Fy, Fz, Mx, My, Mz] divided by wrench_scale {list(c.wrench_scale)} (N, N m), in [-1, 1]")
    metadata = {
        "marinejax_version": __version__,
        "env": config.env,
        "env_overrides": dict(config.env_overrides),
        "checkpoint": str(ckpt),
        "control_dt_s": c.control_dt,
        "observation_size": int(env.observation_size),
        "observation_mode": _observation_mode(c),
        "observation_layout": env.observation_layout(),
        "action_size": int(env.action_size),
        "action": action,
        "frames": "world: x, y horizontal, z up; body: FLU (x forward, y left, z up); SI units",
        "network": f"(obs - mean) / std -> dense {[int(np.shape(policy[n]['kernel'])[1]) for n in layers]} "
                   "with swish between layers -> tanh of the first action_size outputs",
    }
    mirror = None
    if getattr(config.agent, "mirror_symmetric", False):
        from marinejax.envs.symmetry import env_mirror

        m = env_mirror(env)
        mirror = {"obs_perm": m.obs_perm.astype(np.int64), "obs_sign": m.obs_sign, "action_perm": m.action_perm.astype(np.int64),
                  "action_sign": m.action_sign}
        metadata["network"] += ("; mirror-symmetric: the mean averaged with action_sign * mean(observation[obs_perm] * "
                                "obs_sign)[action_perm] before the tanh")
    to_np = lambda x: np.asarray(jax.device_get(x), np.float32)  # noqa: E731
    return PolicyWeights(mean=mean, std=std, kernels=tuple(to_np(policy[n]["kernel"]) for n in layers),
                         biases=tuple(to_np(policy[n]["bias"]) for n in layers), action_size=int(env.action_size),
                         metadata=metadata, mirror=mirror)


def save_npz(weights: PolicyWeights, out: Path) -> Path:
    arrays = {"mean": weights.mean, "std": weights.std, "action_size": np.int64(weights.action_size),
              "metadata": np.array(json.dumps(weights.metadata))}
    for i, (w, b) in enumerate(zip(weights.kernels, weights.biases)):
        arrays[f"kernel_{i}"], arrays[f"bias_{i}"] = w, b
    for name, value in (weights.mirror or {}).items():
        arrays[f"mirror_{name}"] = value
    with open(out, "wb") as f:  # a file object: np.savez would append .npz to another suffix
        np.savez(f, **arrays)
    return out


def load_numpy_policy(path: Path | str) -> PolicyWeights:
    """The policy exported with `--format npz`, callable on observations (NumPy only)."""
    with np.load(path, allow_pickle=False) as data:
        n = sum(1 for k in data.files if k.startswith("kernel_"))
        return PolicyWeights(mean=data["mean"], std=data["std"], kernels=tuple(data[f"kernel_{i}"] for i in range(n)),
                             biases=tuple(data[f"bias_{i}"] for i in range(n)), action_size=int(data["action_size"]),
                             metadata=json.loads(str(data["metadata"])),
                             mirror={k[len("mirror_"):]: data[k] for k in data.files if k.startswith("mirror_")} or None)


def save_onnx(weights: PolicyWeights, out: Path) -> Path:
    """An ONNX model (opset 17): input "observation" (B, obs) float32, output "action" (B, action)."""
    try:
        import onnx
        from onnx import TensorProto, helper, numpy_helper
    except ImportError:
        raise UserError("ONNX export needs the onnx package: pip install 'marinejax[export]'") from None
    init = [numpy_helper.from_array(weights.mean, "mean"), numpy_helper.from_array(weights.std, "std"),
            numpy_helper.from_array(np.array([0], np.int64), "start"),
            numpy_helper.from_array(np.array([weights.action_size], np.int64), "end"),
            numpy_helper.from_array(np.array([1], np.int64), "axis")]
    for i, (w, b) in enumerate(zip(weights.kernels, weights.biases)):
        init += [numpy_helper.from_array(w, f"kernel_{i}"), numpy_helper.from_array(b, f"bias_{i}")]

    def mean_of(observation: str, p: str) -> tuple[list, str]:
        """Nodes computing the policy's mean (before the tanh) of input `observation`, names prefixed `p`."""
        nodes = [helper.make_node("Sub", [observation, "mean"], [f"{p}centred"]), helper.make_node("Div", [f"{p}centred", "std"], [f"{p}x0"])]
        x = f"{p}x0"
        for i in range(len(weights.kernels)):
            nodes.append(helper.make_node("Gemm", [x, f"kernel_{i}", f"bias_{i}"], [f"{p}dense_{i}"]))
            x = f"{p}dense_{i}"
            if i < len(weights.kernels) - 1:
                nodes += [helper.make_node("Sigmoid", [x], [f"{p}sigmoid_{i}"]), helper.make_node("Mul", [x, f"{p}sigmoid_{i}"], [f"{p}swish_{i}"])]
                x = f"{p}swish_{i}"
        return nodes + [helper.make_node("Slice", [x, "start", "end", "axis"], [f"{p}loc"])], f"{p}loc"

    nodes, loc = mean_of("observation", "")
    if weights.mirror is not None:
        init += [numpy_helper.from_array(np.asarray(v), f"mirror_{k}") for k, v in weights.mirror.items()]
        init.append(numpy_helper.from_array(np.array(0.5, np.float32), "half"))
        nodes += [helper.make_node("Gather", ["observation", "mirror_obs_perm"], ["reflected_raw"], axis=1),
                  helper.make_node("Mul", ["reflected_raw", "mirror_obs_sign"], ["reflected"])]
        image_nodes, image = mean_of("reflected", "image_")
        nodes += image_nodes + [
            helper.make_node("Gather", [image, "mirror_action_perm"], ["image_permuted"], axis=1),
            helper.make_node("Mul", ["image_permuted", "mirror_action_sign"], ["image_reflected"]),
            helper.make_node("Add", [loc, "image_reflected"], ["loc_sum"]),
            helper.make_node("Mul", ["loc_sum", "half"], ["loc_symmetric"]),
        ]
        loc = "loc_symmetric"
    nodes.append(helper.make_node("Tanh", [loc], ["action"]))
    obs_size = int(weights.mean.shape[0])
    graph = helper.make_graph(
        nodes, "marinejax_policy",
        [helper.make_tensor_value_info("observation", TensorProto.FLOAT, ["batch", obs_size])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["batch", weights.action_size])],
        init,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="marinejax")
    model.ir_version = 8  # readable by onnxruntime >= 1.14
    helper.set_model_props(model, {"marinejax": json.dumps(weights.metadata)})
    onnx.checker.check_model(model)
    onnx.save(model, str(out))
    return out


def export_policy(path: Path | str, fmt: str = "onnx", out: Path | None = None, which: str = "best") -> Path:
    """Write the policy of `path` (run directory, checkpoint or shipped env name) as `fmt`."""
    if fmt not in FORMATS:
        raise UserError(f"unknown export format {fmt!r}; valid: {list(FORMATS)}")
    weights = policy_weights(path, which)
    out = Path(out) if out else Path(f"{weights.metadata['env']}-policy.{fmt}")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        return save_npz(weights, out) if fmt == "npz" else save_onnx(weights, out)
    except OSError as err:  # a read-only or special directory, a full disk: the user's path
        raise UserError(f"cannot write {out}: {err.strerror or err}") from None
