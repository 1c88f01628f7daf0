"""Compatibility of brax 0.14.2 with jax >= 0.10.

brax 0.14.2's `ppo.train` (and its `pmap` helpers) call `jax.device_put_replicated`, which jax 0.10
removed. `install()` puts an equivalent back on the `jax` module, only when it is missing. Delete
this module once the lowest supported brax is a release that no longer calls it (brax's main branch
already does not).
"""

from __future__ import annotations

from typing import Any, Sequence

import warnings

import jax
import numpy as np


def device_put_replicated(x: Any, devices: Sequence[jax.Device]) -> Any:
    """Copy every leaf of pytree `x` to each of `devices`, stacked along a new leading axis of length
    `len(devices)` and sharded over it (one copy per device), as `jax.pmap` expects its inputs."""
    devices = list(devices)
    if not devices:
        raise ValueError("device_put_replicated needs at least one device")
    mesh = jax.sharding.Mesh(np.array(devices), ("replica",))
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("replica"))

    def put(leaf: Any) -> jax.Array:
        stacked = np.broadcast_to(np.asarray(leaf), (len(devices), *np.shape(leaf)))
        return jax.device_put(stacked, sharding)

    return jax.tree.map(put, x)


def install() -> bool:
    """Add `jax.device_put_replicated` if this jax lacks it; True when it was added."""
    try:
        with warnings.catch_warnings():  # jax 0.8-0.9 deprecate it on access
            warnings.simplefilter("ignore", DeprecationWarning)
            jax.device_put_replicated  # noqa: B018
        return False
    except AttributeError:
        jax.device_put_replicated = device_put_replicated
        return True
