"""Validation figures of the physics against closed-form results, printed by `marinejax validate`.

Each row: a quantity measured from the simulator, the closed-form value it must match, and the
relative difference. The same checks, with their tolerances, are asserted in tests/test_physics.py.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from marinejax.frames import quat_from_euler, quat_to_euler
from marinejax.physics import VehicleState, rollout
from marinejax.vehicle import Vehicle


def _steady(lin: float, quad: float, force: float) -> float:
    """Root u >= 0 of lin·u + quad·u² = force."""
    return force / lin if quad == 0 else (-lin + math.sqrt(lin**2 + 4 * quad * force)) / (2 * quad)


def validation_table(vehicle: Vehicle, dt: float = 0.05, seconds: float = 10.0) -> list[tuple[str, float, float, str]]:
    """Rows (name, measured, expected, unit) for axis force steps, passive roll and heave stability."""
    sys = vehicle.sys
    h = sys.hydro
    m = float(sys.model.body_mass[sys.body_id])
    inertia = np.asarray(sys.model.body_inertia[sys.body_id])
    g = -float(sys.model.opt.gravity[2])
    buoyancy = float(h.fluid_density * g * h.volume)
    net = buoyancy - m * g
    steps = int(round(seconds / dt))
    forces = [(0, 12.0, "surge"), (1, 12.0, "sway"), (2, -15.0, "heave")]
    n = len(forces) + 1
    wrench = np.zeros((n, steps, 6), np.float32)
    for row, (axis, f, _) in enumerate(forces):
        wrench[row, :, axis] = f
    roll0 = math.radians(5.0)
    quat = np.stack([np.array([1.0, 0, 0, 0])] * len(forces) + [np.asarray(quat_from_euler(roll0, 0.0, 0.0))])
    state = VehicleState(
        position=jnp.zeros((n, 3)),
        quaternion=jnp.asarray(quat, jnp.float32),
        velocity=jnp.zeros((n, 3)),
        angular_velocity=jnp.zeros((n, 3)),
        actuators=jnp.zeros((n, vehicle.num_actuators)),
    )
    traj = rollout(vehicle, wrench, state, control_dt=dt, substeps=1, mode="wrench")
    rows = []
    for row, (axis, f, name) in enumerate(forces):
        total = f + (net if axis == 2 else 0.0)
        # acceleration at t = 0 from the first two steps, v(t) ≈ a t + b t²/2: a = (4 v(dt) − v(2 dt)) / (2 dt)
        v1, v2 = float(traj.velocity[row, 0, axis]), float(traj.velocity[row, 1, axis])
        rows.append((f"{name} initial acceleration, {f:+.0f} N", (4 * v1 - v2) / (2 * dt),
                     total / (m + float(h.added_mass[axis])), "m/s²"))
        speed = math.copysign(_steady(float(h.linear_damping[axis]), float(h.quadratic_damping[axis]), abs(total)), total)
        rows.append((f"{name} steady speed, {f:+.0f} N", float(traj.velocity[row, -1, axis]), speed, "m/s"))
    roll = np.asarray(quat_to_euler(traj.quaternion[-1]))[:, 0]
    t = np.asarray(traj.time)
    i = np.where((roll[:-1] > 0) & (roll[1:] <= 0))[0]
    crossings = t[i] + dt * roll[i] / (roll[i] - roll[i + 1])
    bg = float(h.center_of_buoyancy[2])
    period = 2 * math.pi * math.sqrt((inertia[0] + float(h.added_mass[3])) / (buoyancy * bg))
    rows.append(("small-angle roll period, 5°", float(np.mean(np.diff(crossings))) if len(crossings) > 1 else float("nan"), period, "s"))
    return rows


def print_validation(vehicle: Vehicle, dt: float = 0.05) -> list[tuple[str, float, float, str]]:
    """Compute and print the validation table with rich; returns the rows."""
    from rich.console import Console
    from rich.table import Table

    rows = validation_table(vehicle, dt=dt)
    table = Table(title=f"{vehicle.name} ({vehicle.param_set}), physics dt {dt} s: simulator vs closed form")
    for col in ("quantity", "simulated", "closed form", "unit", "difference"):
        table.add_column(col, justify="left" if col == "quantity" else "right")
    for name, measured, expected, unit in rows:
        table.add_row(name, f"{measured:.4f}", f"{expected:.4f}", unit, f"{100 * (measured - expected) / expected:+.2f} %")
    Console().print(table)
    return rows
