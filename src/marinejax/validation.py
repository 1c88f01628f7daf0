"""Validation figures of the physics, printed by `marinejax validate`.

Each row: a quantity measured from the simulator, the value it must match, and the relative
difference. ROVs: closed-form results (the same checks, with their tolerances, are asserted in
tests/test_physics.py). The REMUS 100 torpedo: the figures of its reference implementation
(`torpedo_table`; asserted in tests/test_remus100.py).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from marinejax.actuators.fin import steering_mix
from marinejax.frames import quat_from_euler, quat_to_euler, quat_to_mat
from marinejax.physics import VehicleState, initial_state, rollout
from marinejax.vehicle import Vehicle

# The Marine Systems Simulator's remus100 (Python Vehicle Simulator, commit c717e07, MIT; Fossen 2021,
# section 8.4.2), run unmodified on its own dynamics with SciPy DOP853 at rtol 1e-9 (2026-12-01).
# Angles in the reference's FRD convention; a positive rudder turns to starboard, positive stern
# planes pitch the nose down.
REMUS100_REFERENCE = {
    "terminal speed, 1525 rpm": (2.553645562, "m/s"),
    "turning diameter, rudder 15°": (36.9235, "m"),
    "turn rate, rudder 15°": (7.77884, "°/s"),
    "heel into the turn, rudder 15°": (3.0052, "°"),
    "pitch after 5 s of stern planes 10°": (-42.735, "°"),
    "depth gained in those 5 s": (4.527, "m"),
    "roll period, free decay from 10°": (1.0419, "s"),
}

# The Marine Systems Simulator's four-fin torpedo (torpedo.py of the same repository and commit: the
# REMUS 100 hull with four independent fins, no fin drag, a 0.1 s propeller lag), run unmodified with
# the simulator's own Euler integration at 5 ms and 2.5 ms, extrapolated to zero step (Richardson; the
# roll period at 1 and 0.5 ms), a fresh vehicle for each manoeuvre (its actuators keep their state),
# 2026-12-01. Fin commands as in `remus100_four_fin.xml`: the rudder is the top fin at +δ
# and the bottom one at −δ, the stern planes the starboard fin at +δ and the port one at −δ.
FOUR_FIN_REFERENCE = {
    "terminal speed, 1525 rpm": (2.553645562, "m/s"),
    "turning diameter, rudder 15°": (36.8532, "m"),
    "turn rate, rudder 15°": (7.87349, "°/s"),
    "heel into the turn, rudder 15°": (3.0359, "°"),
    "pitch after 5 s of stern planes 10°": (-43.328, "°"),
    "depth gained in those 5 s": (4.608, "m"),
    "roll after 10 s, all four fins at +5°": (-3.3682, "°"),
    "roll period, free decay from 10°": (1.0419, "s"),
}


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

    if vehicle.name in TORPEDO_REFERENCES:
        rows, against = torpedo_table(vehicle, dt=dt), "reference implementation"
    else:
        rows, against = validation_table(vehicle, dt=dt), "closed form"
    table = Table(title=f"{vehicle.name} ({vehicle.param_set}), physics dt {dt} s: simulator vs {against}")
    for col in ("quantity", "simulated", against, "unit", "difference"):
        table.add_column(col, justify="left" if col == "quantity" else "right")
    for name, measured, expected, unit in rows:
        table.add_row(name, f"{measured:.4f}", f"{expected:.4f}", unit, f"{100 * (measured - expected) / expected:+.2f} %")
    Console().print(table)
    return rows


def torpedo_manoeuvres(vehicle: Vehicle, dt: float = 0.05) -> dict[str, float]:
    """The REMUS reference's manoeuvres simulated (actions [rudder, stern planes, propeller] in
    [−1, 1]; the propeller's +1 is its max_rpm): straight at full speed, a steady turn at full rudder
    (15°) and stern planes at 10° for 5 s from the straight run, a free roll decay at rest. Values in
    the reference's units and FRD angle conventions (REMUS100_REFERENCE's keys)."""
    rudder, stern = (vehicle.sys.actuators[i].params.max_angle for i in (0, 1))
    mix = steering_mix(vehicle.sys.actuators)  # identity for the REMUS's rudder and stern planes
    per_s = int(round(1 / dt))

    def actions(rudder_rad, stern_rad, steps):
        return np.tile(mix @ np.array([rudder_rad / float(rudder), stern_rad / float(stern), 1.0], np.float32), (steps, 1))

    straight = rollout(vehicle, actions(0, 0, 60 * per_s), control_dt=dt)
    start = initial_state(vehicle, quaternion=straight.quaternion[-1], velocity=straight.velocity[-1],
                          angular_velocity=straight.angular_velocity[-1], actuators=straight.actuators[-1])
    turn = rollout(vehicle, actions(math.radians(15), 0, 80 * per_s), start, control_dt=dt)
    rot = np.asarray(quat_to_mat(turn.quaternion[-1]))
    xy = np.asarray(turn.position[-50 * per_s:, :2])  # the last 50 s: more than a revolution
    dive = rollout(vehicle, actions(0, math.radians(10), 5 * per_s), start, control_dt=dt)
    nose = np.asarray(quat_to_mat(dive.quaternion[-1]))[2, 0]  # world z of the body's x axis
    rest = initial_state(vehicle, quaternion=(math.cos(math.radians(5)), math.sin(math.radians(5)), 0.0, 0.0))
    decay = rollout(vehicle, np.tile(mix @ np.array([0, 0, -1], np.float32), (120, 1)), rest, control_dt=0.025)
    roll = np.asarray(quat_to_euler(decay.quaternion))[:, 0]
    t = np.asarray(decay.time)
    i = np.where((roll[:-1] > 0) & (roll[1:] <= 0))[0]
    crossings = t[i] + 0.025 * roll[i] / (roll[i] - roll[i + 1])
    extra = {}
    if mix.shape[0] == 5:  # four independent fins: all at +5° roll the vehicle
        fins = np.where(mix[:, 2] == 0, math.radians(5) / float(rudder), 1.0).astype(np.float32)
        rolled = rollout(vehicle, np.tile(fins, (10 * per_s, 1)), start, control_dt=dt)
        extra["roll after 10 s, all four fins at +5°"] = math.degrees(float(quat_to_euler(rolled.quaternion[-1])[0]))
    return {**extra,
        "terminal speed, 1525 rpm": float(np.linalg.norm(straight.velocity[-1])),
        "turning diameter, rudder 15°": float(np.ptp(xy[:, 0]) + np.ptp(xy[:, 1])) / 2,
        "turn rate, rudder 15°": -math.degrees(float(rot[2] @ np.asarray(turn.angular_velocity[-1]))),
        "heel into the turn, rudder 15°": math.degrees(math.atan2(float(rot[2, 1]), float(rot[2, 2]))),
        "pitch after 5 s of stern planes 10°": math.degrees(math.asin(float(nose))),
        "depth gained in those 5 s": -float(dive.position[-1, 2] - start.position[2]),
        "roll period, free decay from 10°": float(np.mean(np.diff(crossings))),
    }


TORPEDO_REFERENCES = {"remus100": REMUS100_REFERENCE, "remus100_four_fin": FOUR_FIN_REFERENCE}


def torpedo_table(vehicle: Vehicle, dt: float = 0.05) -> list[tuple[str, float, float, str]]:
    """Rows (name, measured, reference, unit) of a torpedo of `TORPEDO_REFERENCES` against its reference implementation."""
    measured = torpedo_manoeuvres(vehicle, dt)
    return [(name, measured[name], value, unit) for name, (value, unit) in TORPEDO_REFERENCES[vehicle.name].items()]
