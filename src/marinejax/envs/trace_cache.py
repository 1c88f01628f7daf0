"""The training env's batched reset and step, kept on disk as `jax.export` artifacts between processes.

A fresh training process spends most of the time before its first evaluation tracing the env's reset
and step, batching them (vmap), wrapping them for training and lowering them to StableHLO: about 2 s
on a 2-core CPU. JAX's persistent compilation cache cannot skip that work, because it looks compiled
programs up by their lowered text. `TraceCache`, the outermost training wrapper, therefore exports
the wrapped reset and step to `cache_dir` the first time and, in a later process, loads and calls
them untraced.

An artifact is used only when everything the traced program depends on is unchanged. Its key hashes:
- the classes of the env and its wrappers, the env's config, and their public plain attributes (a
  tracking task's `kind`, the episode length);
- the plant's constants (the MuJoCo model, every array of the MJX model, fluid and thruster parameters);
- the input shapes and pytree structure (so each batch size has its own artifact);
- the marinejax source files (*.py), the jax, jaxlib, mujoco and brax versions, the JAX platform and
  the JAX settings that change traced numerics (x64, PRNG implementation, matmul precision).
Files are written atomically, so concurrent runs may share one directory. Only the CPU backend uses
the cache (the one it was tested on); on a GPU the env is traced in every process as before.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import re
import tempfile
from importlib.metadata import version
from pathlib import Path
from typing import Any, Callable

import jax
import mujoco
import numpy as np
from brax.envs.base import State, Wrapper
from jax import export

from marinejax.envs.base import MarineEnv
from marinejax.errors import UserError

_JAX_SETTINGS = ("jax_enable_x64", "jax_default_prng_impl", "jax_threefry_partitionable", "jax_default_matmul_precision")
_SUFFIX = ".jaxexport"


def _source_digest() -> str:
    """sha256 of marinejax's Python source files, names included."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def env_fingerprint(env: Any) -> str:
    """sha256 of what a (wrapped) env's traced reset and step depend on besides their inputs
    (module docstring).

    `env` is a `MarineEnv` or Brax wrappers over one. Of the env and of each wrapper, the public
    attributes holding plain values (str, int, float, bool, None, tuples) enter with the classes and
    the config: a task or wrapper whose constructor takes more must store it so, or in its config."""
    layers = []
    while isinstance(env, Wrapper):
        layers.append(env)
        env = env.env
    if not isinstance(env, MarineEnv):
        raise UserError(f"the trace cache needs a marinejax env (a MarineEnv, or wrappers over one), got {type(env).__name__}")
    h = hashlib.sha256()
    settings = {name: str(getattr(jax.config, name, None)) for name in _JAX_SETTINGS}
    versions = {p: version(p) for p in ("jax", "jaxlib", "mujoco", "mujoco-mjx", "brax")}
    h.update(repr(([_describe(layer) for layer in layers], _describe(env), repr(env.config), settings, versions,
                   jax.default_backend(), _source_digest())).encode())
    model = env.vehicle.mj_model
    mjb = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, mjb)
    h.update(mjb.tobytes())  # the MuJoCo model, whose arrays MJX keeps as static (non-leaf) data
    leaves, treedef = jax.tree.flatten(env.plant.sys)
    h.update(_structure(treedef).encode())
    for leaf in leaves:
        a = np.asarray(leaf)
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _describe(obj: Any) -> tuple:
    """An object's class and its public attributes that hold plain values."""
    cls = type(obj)
    plain = {k: v for k, v in vars(obj).items()
             if not k.startswith("_") and isinstance(v, (str, int, float, bool, type(None), tuple))}
    return cls.__module__, cls.__qualname__, sorted(plain.items())


def _structure(treedef: Any) -> str:
    """A pytree structure as text, without the object addresses with which MJX's static arrays print
    (their contents are the MuJoCo model's, which the fingerprint hashes)."""
    return re.sub(r" at 0x[0-9a-fA-F]+", "", str(treedef))


def _load_lapack() -> None:
    """Make jaxlib load its CPU LAPACK kernels, as lowering any LAPACK op does. A deserialized export
    that calls them (MJX's Cholesky solve) in a process that never lowered one jumps to a null
    kernel pointer and crashes (jax issue #29610)."""
    jax.jit(jax.numpy.linalg.cholesky).lower(jax.ShapeDtypeStruct((1, 1), np.float32))


def _write_atomically(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


class TraceCache(Wrapper):
    """A batched env (the training wrappers over a `MarineEnv`) whose `reset` and `step` are kept in
    `cache_dir` as `jax.export` artifacts: exported on first use, loaded and called untraced by later
    processes (module docstring). The numbers are those of the wrapped env's own functions."""

    def __init__(self, env: Wrapper, cache_dir: str | Path):
        super().__init__(env)
        self.cache_dir = Path(cache_dir)
        self._fingerprint: str | None = None
        self._calls: dict[str, Callable[[list], Any]] = {}

    def reset(self, rng: jax.Array) -> State:
        return self._cached("reset", self.env.reset, (rng,))

    def step(self, state: State, action: jax.Array) -> State:
        return self._cached("step", self.env.step, (state, action))

    def _cached(self, name: str, fn: Callable[..., Any], args: tuple) -> Any:
        if jax.default_backend() != "cpu":  # tested on CPU only: elsewhere the env is traced as usual
            return fn(*args)
        leaves, in_tree = jax.tree.flatten(args)
        avals = [jax.typeof(x) for x in leaves]
        if self._fingerprint is None:
            self._fingerprint = env_fingerprint(self.env)
        key = hashlib.sha256(repr((name, self._fingerprint, _structure(in_tree), [str(a) for a in avals])).encode()).hexdigest()
        call = self._calls.get(key)
        if call is None:
            call = self._calls[key] = self._load_or_export(self.cache_dir / f"{name}-{key[:32]}{_SUFFIX}", fn, in_tree, avals)
        return call(leaves)

    @staticmethod
    def _load_or_export(path: Path, fn: Callable[..., Any], in_tree: Any, avals: list) -> Callable[[list], Any]:
        record = None
        if path.exists():
            _load_lapack()  # exporting lowers the LAPACK ops itself, which loads them
            try:
                record = pickle.loads(path.read_bytes())
                exported = export.deserialize(bytearray(record["exported"]))
            except Exception:  # a truncated or foreign file: export it again over it
                record = None
        if record is None:
            out_tree = []

            def flat(*leaves):
                out, tree = jax.tree.flatten(fn(*jax.tree.unflatten(in_tree, leaves)))
                out_tree.append(tree)
                return out

            specs = [jax.ShapeDtypeStruct(a.shape, a.dtype, weak_type=a.weak_type) for a in avals]
            record = {"exported": export.export(jax.jit(flat))(*specs).serialize(), "out_tree": out_tree[0]}
            _write_atomically(path, pickle.dumps(record))
            # the program later processes load, so that this one compiles (and caches) the same one
            exported = export.deserialize(bytearray(record["exported"]))
        out_tree = record["out_tree"]
        return lambda leaves: jax.tree.unflatten(out_tree, exported.call(*leaves))
