"""Hydrodynamic coefficients of one vehicle as an immutable JAX pytree."""

from __future__ import annotations

from typing import Mapping

import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.errors import UserError

_SIZES = {
    "added_mass": 6,
    "linear_damping": 6,
    "quadratic_damping": 6,
    "volume": 1,
    "fluid_density": 1,
    "center_of_buoyancy": 3,
}
_NONNEGATIVE = ("added_mass", "linear_damping", "quadratic_damping")
_POSITIVE = ("volume", "fluid_density")


@struct.dataclass
class HydroParams:
    """Fluid coefficients of a vehicle, body frame FLU, about the centre of gravity.

    All matrices are diagonal (as in every published BlueROV2 set) and stored as their diagonals,
    ordered (surge, sway, heave, roll, pitch, yaw). Values are positive magnitudes (SNAME: M_A =
    -diag(Xu̇, ...), D_L = -diag(Xu, ...)).
    """

    added_mass: jnp.ndarray  # (6,) kg (linear), kg m^2 (angular)
    linear_damping: jnp.ndarray  # (6,) N s/m, N m s/rad
    quadratic_damping: jnp.ndarray  # (6,) N s^2/m^2, N m s^2/rad^2
    volume: jnp.ndarray  # () displaced volume, m^3
    fluid_density: jnp.ndarray  # () kg/m^3
    center_of_buoyancy: jnp.ndarray  # (3,) m, body frame FLU, relative to the centre of gravity

    @classmethod
    def from_mapping(cls, values: Mapping[str, object], source: str = "parameters") -> "HydroParams":
        """Validate plain numbers and build the pytree.

        Raises ValueError naming the field (and `source`) on a missing, unknown, misshaped,
        non-finite or physically impossible value.
        """
        unknown = sorted(set(values) - set(_SIZES))
        if unknown:
            raise UserError(f"{source}: unknown hydrodynamic field(s) {unknown}; valid: {sorted(_SIZES)}")
        missing = sorted(set(_SIZES) - set(values))
        if missing:
            raise UserError(f"{source}: missing hydrodynamic field(s) {missing}")
        arrays = {}
        for name, size in _SIZES.items():
            arr = np.asarray(values[name], dtype=np.float64).reshape(-1)
            if arr.size != size:
                raise UserError(f"{source}: '{name}' needs {size} value(s), got {arr.size}: {arr.tolist()}")
            if not np.all(np.isfinite(arr)):
                raise UserError(f"{source}: '{name}' has non-finite values {arr.tolist()}")
            if name in _NONNEGATIVE and np.any(arr < 0):
                raise UserError(f"{source}: '{name}' must be >= 0 (positive magnitudes), got {arr.tolist()}")
            if name in _POSITIVE and np.any(arr <= 0):
                raise UserError(f"{source}: '{name}' must be > 0, got {arr.tolist()}")
            # cast on the host: a float64 array given to JAX is converted by a compiled program
            arrays[name] = jnp.asarray(np.float32(arr) if size > 1 else np.float32(arr[0]))
        return cls(**arrays)

    def replace_values(self, **changes: object) -> "HydroParams":
        """Copy with some fields changed, validated like `from_mapping`."""
        current = {k: np.asarray(getattr(self, k)) for k in _SIZES}
        current.update(changes)
        return HydroParams.from_mapping(current, source="HydroParams.replace_values")
