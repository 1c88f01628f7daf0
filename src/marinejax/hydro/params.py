"""Hydrodynamic coefficients of one vehicle as an immutable JAX pytree."""

from __future__ import annotations

from typing import Mapping

import jax.numpy as jnp
import numpy as np
from flax import struct

from marinejax.errors import UserError
import marinejax.hydro.hull as hull_terms

_SIZES = {
    "added_mass": 6,
    "linear_damping": 6,
    "quadratic_damping": 6,
    "volume": 1,
    "fluid_density": 1,
    "center_of_buoyancy": 3,
}
FIELDS = tuple(_SIZES)  # the required fields, in the order parameter sets and files list them
# optional fields and their defaults (the ROVs use none of them)
_OPTIONAL = {
    "reference_point": np.zeros(3),
    "damping_fade": np.zeros(6),
    "added_mass_munk_terms": np.ones(1),
}
_NONNEGATIVE = ("added_mass", "linear_damping", "quadratic_damping", "damping_fade")
_POSITIVE = ("volume", "fluid_density")


@struct.dataclass
class HydroParams:
    """Fluid coefficients of a vehicle, body frame FLU, ordered (surge, sway, heave, roll, pitch,
    yaw), about its hydrodynamic reference point: the centre of gravity (the ROVs) or the point
    `reference_point` (m, from the CG) where a published model is written (the REMUS 100's centre of
    buoyancy). Values are positive magnitudes (SNAME: M_A = -[Xu̇ ...], D_L = -diag(Xu, ...)).

    Added mass is a symmetric 6 × 6 matrix: its diagonal in `added_mass` and the rest in
    `added_mass_coupling` (zero diagonal), e.g. a torpedo's heave–pitch and sway–yaw terms or a
    diagonal matrix moved from the centre of buoyancy to the CG. A file gives either its 6 diagonal
    values (every published BlueROV2 set) or all 36, row by row.

    Damping matrices are diagonal; the linear damping fades with the relative speed U_r (m/s) as
    exp(−damping_fade · U_r) (the REMUS model lets its surge and sway damping give way to the hull's
    quadratic drag and lift). `added_mass_munk_terms` 0 drops the Munk moments and the surge row of
    C_A (the REMUS reference code does, Fossen 2021 section 8.4.2; 1, physical, keeps the whole
    C_A). `hull`: a slender hull's lift, drag and cross-flow drag (`hydro/hull.py`), or None.
    `simple` (static, set at load): diagonal M_A about the CG, no fading, whole C_A, no hull; then
    the equations keep the cheaper diagonal form.
    """

    added_mass: jnp.ndarray  # (6,) diagonal of M_A: kg (linear), kg m^2 (angular)
    added_mass_coupling: jnp.ndarray  # (6, 6) off-diagonal part of M_A (kg, kg m, kg m^2), symmetric, zero diagonal
    linear_damping: jnp.ndarray  # (6,) N s/m, N m s/rad
    quadratic_damping: jnp.ndarray  # (6,) N s^2/m^2, N m s^2/rad^2
    volume: jnp.ndarray  # () displaced volume, m^3
    fluid_density: jnp.ndarray  # () kg/m^3
    center_of_buoyancy: jnp.ndarray  # (3,) m, body frame FLU, relative to the centre of gravity
    reference_point: jnp.ndarray  # (3,) m, body frame FLU, from the CG: where the coefficients are given
    damping_fade: jnp.ndarray  # (6,) s/m, linear damping × exp(−fade · U_r)
    hull: hull_terms.HullParams | None = None
    munk_terms: bool = struct.field(pytree_node=False, default=True)
    simple: bool = struct.field(pytree_node=False, default=True)

    def added_mass_matrix(self) -> jnp.ndarray:
        """M_A (6, 6) (leading batch axes allowed)."""
        return self.added_mass[..., :, None] * jnp.eye(6) + self.added_mass_coupling

    @classmethod
    def from_mapping(cls, values: Mapping[str, object], source: str = "parameters") -> "HydroParams":
        """Validate plain numbers and build the pytree.

        Raises ValueError naming the field (and `source`) on a missing, unknown, misshaped,
        non-finite or physically impossible value.
        """
        unknown = sorted(set(values) - set(_SIZES) - set(_OPTIONAL) - set(hull_terms.FIELDS))
        if unknown:
            raise UserError(f"{source}: unknown hydrodynamic field(s) {unknown}; valid: "
                            f"{sorted(_SIZES)}, optional {sorted(_OPTIONAL)} and a slender hull's {sorted(hull_terms.FIELDS)}")
        hull = hull_terms.HullParams.from_mapping(values, source)
        values = {**_OPTIONAL, **{k: v for k, v in values.items() if k not in hull_terms.FIELDS}}
        missing = sorted(set(_SIZES) - set(values))
        if missing:
            raise UserError(f"{source}: missing hydrodynamic field(s) {missing}")
        arrays = {}
        coupling = np.zeros((6, 6))
        sizes = {**_SIZES, **{k: v.size for k, v in _OPTIONAL.items()}}
        for name, size in sizes.items():
            arr = np.asarray(values[name], dtype=np.float64).reshape(-1)
            if name == "added_mass" and arr.size == 36:
                arr, coupling = _split_added_mass(arr, source)
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
        munk = float(arrays.pop("added_mass_munk_terms"))
        if munk not in (0.0, 1.0):
            raise UserError(f"{source}: 'added_mass_munk_terms' must be 0 or 1, got {munk}")
        simple = (not np.any(coupling != 0) and not np.any(np.asarray(values["reference_point"], float) != 0)
                  and not np.any(np.asarray(values["damping_fade"], float) != 0) and munk == 1.0 and hull is None)
        return cls(**arrays, added_mass_coupling=jnp.asarray(np.float32(coupling)), hull=hull, munk_terms=munk == 1.0, simple=simple)

    def replace_values(self, **changes: object) -> "HydroParams":
        """Copy with some fields changed, validated like `from_mapping` (`added_mass`: 6 or 36 values)."""
        if not self.simple:
            raise UserError("HydroParams.replace_values supports the simple (ROV) form only")
        current = {k: np.asarray(getattr(self, k)) for k in _SIZES}
        current.update(changes)
        return HydroParams.from_mapping(current, source="HydroParams.replace_values")


def _split_added_mass(values: np.ndarray, source: str) -> tuple[np.ndarray, np.ndarray]:
    """36 values of M_A (row by row) → (diagonal (6,), coupling (6, 6)); symmetric, and positive
    on the diagonal, or a UserError."""
    m = values.reshape(6, 6)
    if not np.all(np.isfinite(m)):
        raise UserError(f"{source}: 'added_mass' has non-finite values {values.tolist()}")
    if not np.allclose(m, m.T, rtol=1e-6, atol=1e-9):
        i, j = np.unravel_index(np.argmax(np.abs(m - m.T)), m.shape)
        raise UserError(f"{source}: the 6 x 6 'added_mass' must be symmetric; entry ({i}, {j}) = {m[i, j]} but ({j}, {i}) = {m[j, i]}")
    m = 0.5 * (m + m.T)
    return np.diag(m).copy(), m - np.diag(np.diag(m))
