"""Physics throughput: batched marinejax vs bare MJX vs a one-vehicle-at-a-time NumPy loop.

    marinejax bench physics [--batch-sizes 1,16,256,1024,4096,16384] [--steps 20] [--out table.json]
    python -m marinejax.benchmarks.physics ...

For each batch size B it times, excluding compilation (one untimed call of each variant compiles and
warms up; then full and bare calls alternate and the best call of each is reported):

1. marinejax full: hydrodynamics + T200 thrusters + lag, the jitted batched rollout
   (`marinejax.physics.rollout_batch`, what `marinejax.rollout` calls, without its host-side finite check);
2. bare MJX: the same `mjx.Model`, the same vmap / scan-over-control-steps / scan-over-substeps
   structure, no fluid or thruster forces, so full/bare − 1 is the cost of the hydrodynamics;
3. a NumPy baseline: the same equations written in plain NumPy (float64), one vehicle at a time in a
   Python loop, as a user without marinejax would write them. Its throughput does not depend on B.

vehicle-steps/s = B × control steps × substeps / seconds (physics steps summed over the batch);
real-time factor = B × control steps × control_dt / seconds (simulated seconds per wall second,
summed over the batch).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from pathlib import Path

from marinejax.benchmarks.common import (
    MIN_TIMED_CALLS,
    MIN_TIMED_SECONDS,
    fmt_rate,
    parse_batch_sizes,
    positive,
    time_calls,
)

import numpy as np

from marinejax.console import make_console
from marinejax.errors import UserError
from marinejax.machine import machine_info
from marinejax.physics import DEFAULT_INTEGRATOR, INTEGRATORS, check_integrator

DEFAULT_BATCH_SIZES = "1,16,256,1024,4096,16384"
MAX_BATCH_CPU = 16384
MAX_BATCH_GPU = 65536
# Cap on batch x control steps per timed call: bigger batches get fewer control steps (16384 -> 5
# by default), so a timed call stays around a second on a 2-core CPU and each is repeated.
MAX_VEHICLE_CONTROL_STEPS = 4096 * 20
SANITY_SECONDS = 2.0
SANITY_TOLERANCE_M = 5e-3
TARGET_BATCH = 4096
TARGET_SPEEDUP = 20.0
TARGET_OVERHEAD = 0.20


# --------------------------------------------------------------------------------------------
# NumPy baseline: one vehicle, float64, the equations of marinejax.hydro.forces and
# marinejax.actuators.t200, integrated by the same scheme as the timed marinejax rollout.
# --------------------------------------------------------------------------------------------


class NumpyVehicle:
    """Plain-NumPy model of one vehicle: Fossen's equations (body frame FLU, origin at the CG),
    T200 table lookup with a first-order lag, integrated at physics step `dt` by the same scheme as
    marinejax (`integrator`: "midpoint" or MuJoCo's semi-implicit "euler").

    State: position (3,) world, quaternion (4,) w x y z body→world, world-frame linear velocity (3,)
    and body-frame angular velocity (3,) (MuJoCo's free-joint convention), thrust (N,).
    """

    def __init__(self, vehicle, dt: float, integrator: str = "midpoint"):
        from marinejax.actuators.t200 import load_bollard_table, only_t200

        sys_ = vehicle.sys
        model, hydro = sys_.model, sys_.hydro
        group = only_t200(sys_.actuators, "the NumPy baseline")
        thr = group.params
        body = sys_.body_id
        self.dt = float(dt)
        self.integrator = integrator
        self.mass = float(model.body_mass[body])
        self.inertia = np.asarray(model.body_inertia[body], dtype=np.float64)
        self.g = float(-model.opt.gravity[2])
        self.m_rb = np.diag(np.concatenate([np.full(3, self.mass), self.inertia]))
        self.m_a = np.asarray(hydro.added_mass_matrix(), dtype=np.float64)  # the ROVs': about the CG
        self.m_inv = np.linalg.inv(self.m_rb + self.m_a)  # constant: invert once
        self.d_lin = np.asarray(hydro.linear_damping, dtype=np.float64)
        self.d_quad = np.asarray(hydro.quadratic_damping, dtype=np.float64)
        self.buoyancy = float(hydro.fluid_density) * self.g * float(hydro.volume)  # N
        self.r_cb = np.asarray(hydro.center_of_buoyancy, dtype=np.float64)
        self.allocation = np.asarray(group.design.allocation, dtype=np.float64)
        self.gain = np.asarray(thr.gain, dtype=np.float64)
        tc = float(thr.time_constant)
        self.alpha = 1.0 - math.exp(-self.dt / max(tc, 1e-9))
        self.alpha_half = 1.0 - math.exp(-0.5 * self.dt / max(tc, 1e-9))
        self.num_thrusters = self.allocation.shape[1]
        # T200 bollard curves at the two table voltages around the supply voltage.
        table = load_bollard_table()
        volts = np.array(sorted(table))
        voltage = float(np.clip(float(thr.voltage), volts[0], volts[-1]))
        i = int(np.clip(np.searchsorted(volts, voltage) - 1, 0, len(volts) - 2))
        self.w_hi = (voltage - volts[i]) / (volts[i + 1] - volts[i])
        self.curve_lo, self.curve_hi = table[volts[i]], table[volts[i + 1]]

    # --- thrusters ---------------------------------------------------------------------------
    def thrust_target(self, throttle: np.ndarray) -> np.ndarray:
        """Steady T200 thrust (N) per thruster for throttles in [-1, 1] (clipped)."""
        u = np.clip(throttle, -1.0, 1.0)
        lo = np.interp(u, self.curve_lo[:, 0], self.curve_lo[:, 1])
        hi = np.interp(u, self.curve_hi[:, 0], self.curve_hi[:, 1])
        return self.gain * ((1.0 - self.w_hi) * lo + self.w_hi * hi)

    # --- equations of motion ------------------------------------------------------------------
    @staticmethod
    def rotation(q: np.ndarray) -> np.ndarray:
        w, x, y, z = q
        return np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )

    @staticmethod
    def skew(a: np.ndarray) -> np.ndarray:
        return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])

    @staticmethod
    def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """a × b for 3-vectors (np.cross costs ~30 us per call on small arrays)."""
        return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])

    @classmethod
    def coriolis(cls, m: np.ndarray, nu: np.ndarray) -> np.ndarray:
        """Fossen's m2c: C(ν) (6, 6) of a symmetric mass matrix."""
        mn = m @ nu  # [a; b] = [M11 v + M12 ω; M21 v + M22 ω]
        sa, sb = cls.skew(mn[:3]), cls.skew(mn[3:])
        c = np.zeros((6, 6))
        c[:3, 3:] = -sa
        c[3:, :3] = -sa
        c[3:, 3:] = -sb
        return c

    def acceleration(self, rot: np.ndarray, nu: np.ndarray, tau: np.ndarray, current_world: np.ndarray) -> np.ndarray:
        """ν̇ (6,) from (M_RB + M_A) ν̇ = τ − C_RB(ν)ν − C_A(ν_r)ν_r − D(ν_r)ν_r + g(η) + M_A ν̇_c."""
        omega = nu[3:]
        vc = rot.T @ current_world
        nu_c = np.concatenate([vc, np.zeros(3)])
        nu_c_dot = np.concatenate([-self.cross(omega, vc), np.zeros(3)])
        nu_r = nu - nu_c
        up = rot[2, :]  # world +z in the body frame
        f_b = self.buoyancy * up
        buoyancy = np.concatenate([f_b, self.cross(self.r_cb, f_b)])
        weight = np.concatenate([-self.mass * self.g * up, np.zeros(3)])
        damping = (self.d_lin + self.d_quad * np.abs(nu_r)) * nu_r
        rhs = (
            tau
            - self.coriolis(self.m_rb, nu) @ nu
            - self.coriolis(self.m_a, nu_r) @ nu_r
            - damping
            + buoyancy
            + weight
            + self.m_a @ nu_c_dot
        )
        return self.m_inv @ rhs

    def qacc(self, quat, vel_world, omega, thrust, current_world):
        """(world-frame acceleration of the CG, body angular acceleration): a = R (v̇ + ω × v)."""
        rot = self.rotation(quat)
        v_body = rot.T @ vel_world
        nu_dot = self.acceleration(rot, np.concatenate([v_body, omega]), self.allocation @ thrust, current_world)
        return rot @ (nu_dot[:3] + self.cross(omega, v_body)), nu_dot[3:]

    @staticmethod
    def rotate(quat, omega, dt):
        """quat ⊗ exp(ω dt / 2): rotate by ω dt about the body axis ω/|ω|, renormalised."""
        speed = math.sqrt(omega @ omega)
        if speed == 0.0:
            return quat
        half = 0.5 * speed * dt
        s = math.sin(half) / speed
        w0, x0, y0, z0 = quat
        w1, x1, y1, z1 = math.cos(half), s * omega[0], s * omega[1], s * omega[2]
        quat = np.array(
            [
                w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1,
                w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
                w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1,
                w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1,
            ]
        )
        return quat / math.sqrt(quat @ quat)

    def step(self, pos, quat, vel_world, omega, thrust, target, current_world):
        """One physics step of dt by `self.integrator`; returns the new (pos, quat, vel_world, omega, thrust)."""
        dt = self.dt
        if self.integrator == "euler":  # MuJoCo's semi-implicit Euler: velocity first, then position
            thrust = thrust + self.alpha * (target - thrust)
            acc, omega_dot = self.qacc(quat, vel_world, omega, thrust, current_world)
            vel_world = vel_world + dt * acc
            omega = omega + dt * omega_dot
            return pos + dt * vel_world, self.rotate(quat, omega, dt), vel_world, omega, thrust
        # explicit midpoint, as marinejax.physics.substep
        acc, omega_dot = self.qacc(quat, vel_world, omega, thrust, current_world)
        vel_mid, omega_mid = vel_world + 0.5 * dt * acc, omega + 0.5 * dt * omega_dot
        quat_mid = self.rotate(quat, omega, 0.5 * dt)
        thrust_mid = thrust + self.alpha_half * (target - thrust)
        acc, omega_dot = self.qacc(quat_mid, vel_mid, omega_mid, thrust_mid, current_world)
        return (pos + dt * vel_mid, self.rotate(quat, omega_mid, dt), vel_world + dt * acc, omega + dt * omega_dot,
                thrust + self.alpha * (target - thrust))

    def rollout(self, throttles: np.ndarray, substeps: int, current_world=None) -> np.ndarray:
        """One vehicle from rest at the origin, level; throttles (T, N) held for `substeps` physics
        steps each. Returns the world positions (T, 3) after each control step."""
        current = np.zeros(3) if current_world is None else np.asarray(current_world, dtype=np.float64)
        pos, vel, omega = np.zeros(3), np.zeros(3), np.zeros(3)
        quat = np.array([1.0, 0.0, 0.0, 0.0])
        thrust = np.zeros(self.num_thrusters)
        out = np.empty((len(throttles), 3))
        for k, u in enumerate(throttles):
            target = self.thrust_target(u)
            for _ in range(substeps):
                pos, quat, vel, omega, thrust = self.step(pos, quat, vel, omega, thrust, target, current)
            out[k] = pos
        return out


def time_numpy(npv: NumpyVehicle, throttles: np.ndarray, substeps: int, seconds: float) -> dict:
    """Roll out vehicles one after another (each over `throttles`, (V, T, N), cycled) until
    `seconds` of wall time have passed (at least one vehicle)."""
    vehicles = 0
    start = time.perf_counter()
    while True:
        npv.rollout(throttles[vehicles % len(throttles)], substeps)
        vehicles += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            break
    steps = vehicles * throttles.shape[1] * substeps
    return {"vehicles": vehicles, "physics_steps": steps, "seconds": elapsed, "vehicle_steps_per_s": steps / elapsed}


# --------------------------------------------------------------------------------------------
# JAX timings
# --------------------------------------------------------------------------------------------


@functools.cache
def _bare_rollout():
    """Jitted bare-MJX batch rollout, built on first use (keeps `import` light)."""
    import jax
    from mujoco import mjx

    from marinejax.physics import to_physics, with_timestep

    @functools.partial(jax.jit, static_argnames=("substeps",))
    def bare(sys, state, commands, control_dt, substeps):  # one mjx.step per physics step
        sys = with_timestep(sys, control_dt / substeps)
        model = sys.model

        def single(state, commands):
            def control(data, _command):  # same scan structure as the full rollout; no forces
                def sub(d, _):
                    return mjx.step(model, d), None

                data, _ = jax.lax.scan(sub, data, None, length=substeps)
                return data, (data.qpos, data.qvel)

            _, out = jax.lax.scan(control, to_physics(sys, state).data, commands)
            return out

        return jax.vmap(single)(state, commands)

    return bare




def time_batch(vehicle, batch: int, steps: int, control_dt: float, substeps: int, integrator: str, seed: int = 0) -> dict:
    import jax
    import jax.numpy as jnp

    from marinejax.physics import rollout_batch, initial_state

    rng = np.random.default_rng(seed)
    commands = jnp.asarray(rng.uniform(-0.3, 0.3, (batch, steps, vehicle.num_actuators)), jnp.float32)
    state = jax.tree.map(lambda x: jnp.broadcast_to(x, (batch,) + x.shape), initial_state(vehicle))
    currents = jnp.zeros((batch, steps, 3), jnp.float32)
    dt = jnp.float32(control_dt)
    sys_ = vehicle.sys
    bare = _bare_rollout()

    timed = time_calls({
        "full": lambda: rollout_batch(sys_, state, commands, currents, dt, substeps, "thrusters", True, integrator),
        "bare": lambda: bare(sys_, state, commands, dt, substeps),
    })
    out = rollout_batch(sys_, state, commands, currents, dt, substeps, "thrusters", True, integrator)
    timed["finite"] = bool(np.all(np.isfinite(np.asarray(out.position))))
    return timed


# --------------------------------------------------------------------------------------------
# Reporting
# --------------------------------------------------------------------------------------------








def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="marinejax bench physics",
        description="Physics throughput: batched marinejax (hydrodynamics + thrusters) vs bare MJX vs a NumPy loop.",
    )
    p.add_argument("--vehicle", default="bluerov2_heavy", help="vehicle name (default bluerov2_heavy)")
    p.add_argument("--batch-sizes", type=parse_batch_sizes, default=parse_batch_sizes(DEFAULT_BATCH_SIZES),
                   help=f"comma-separated batch sizes (default {DEFAULT_BATCH_SIZES}; at most {MAX_BATCH_CPU} on CPU, "
                        f"{MAX_BATCH_GPU} on GPU)")
    p.add_argument("--steps", type=positive(int), default=20,
                   help=f"control steps per timed call (default 20; reduced automatically so that "
                        f"batch x steps <= {MAX_VEHICLE_CONTROL_STEPS})")
    p.add_argument("--control-dt", type=positive(float), default=0.05, help="control step in seconds (default 0.05)")
    p.add_argument("--substeps", type=positive(int), default=1, help="physics steps per control step (default 1)")
    p.add_argument("--integrator", choices=INTEGRATORS, default=DEFAULT_INTEGRATOR,
                   help=f"physics integrator (default {DEFAULT_INTEGRATOR}; 'euler' needs steps <= 0.02 s)")
    p.add_argument("--numpy-seconds", type=positive(float), default=5.0,
                   help="wall-clock budget of the NumPy baseline in seconds (default 5)")
    p.add_argument("--out", type=Path, default=None, help="also write the results as JSON to this path")
    return p




def _print_table(console, rows: list[dict], numpy_rate: float, numpy_rtf: float) -> None:
    from rich.table import Table

    table = Table(title="Physics throughput (vehicle-steps/s = physics steps/s summed over the batch; "
                        "RTF = simulated s per wall s, summed over the batch)", title_justify="left")
    for name in ("batch", "ctrl steps", "full s", "full steps/s", "full RTF", "bare MJX s", "bare steps/s",
                 "bare RTF", "hydro overhead", "speedup vs NumPy"):
        table.add_column(name, justify="right")
    for r in rows:
        steps = str(r["steps"]) + ("*" if r["steps_reduced"] else "")
        table.add_row(
            str(r["batch"]), steps,
            f"{r['full_seconds']:.4f}", fmt_rate(r["full_vehicle_steps_per_s"]), fmt_rate(r["full_rtf"]),
            f"{r['bare_seconds']:.4f}", fmt_rate(r["bare_vehicle_steps_per_s"]), fmt_rate(r["bare_rtf"]),
            f"{100 * r['hydro_overhead']:+.1f} %", f"{r['speedup_vs_numpy']:.1f}x",
        )
    table.add_row("NumPy (1 at a time)", "", "", fmt_rate(numpy_rate), fmt_rate(numpy_rtf), "", "", "", "", "1.0x")
    console.print(table)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    total_start = time.perf_counter()

    import jax.numpy as jnp

    import marinejax

    console = make_console()
    info = machine_info()
    max_batch = MAX_BATCH_GPU if info["backend"] == "gpu" else MAX_BATCH_CPU
    too_big = [b for b in args.batch_sizes if b > max_batch]
    if too_big:
        parser.error(f"batch sizes {too_big} exceed {max_batch} on the {info['backend']} backend "
                     f"(up to {MAX_BATCH_GPU} with a GPU)")
    try:
        vehicle = marinejax.load_vehicle(args.vehicle)
    except UserError as err:
        print(f"marinejax bench physics: error: {err}", file=sys.stderr)
        return 2

    physics_dt = args.control_dt / args.substeps
    try:
        check_integrator(args.integrator, physics_dt)
    except UserError as err:
        parser.error(str(err))
    console.print("[bold]marinejax physics benchmark[/bold]")
    console.print(f"machine: {info['cpu']} | {info['cpu_count']} cores ({info['cpus_usable']} usable) | {info['platform']}"
                  + (f" | load average {info['load_average'][0]:.2f} at start (other work on the machine skews timings)"
                     if info["load_average"] else ""))
    console.print(f"python {info['python']}, numpy {info['numpy']}, jax {info['jax']} (jaxlib {info['jaxlib']}), "
                  f"mujoco {info['mujoco']}; backend {info['backend']}, devices {info['devices']}")
    console.print(f"vehicle {vehicle.name} ({vehicle.num_actuators} thrusters, parameter set {vehicle.param_set}); "
                  f"control dt {args.control_dt:g} s x {args.substeps} substeps -> physics dt {physics_dt:g} s, "
                  f"{args.integrator} integrator; "
                  f"random throttles in [-0.3, 0.3], seed 0")
    console.print("timings exclude compilation: one call compiles and warms up, then full and bare calls alternate "
                  f"(at least {MIN_TIMED_CALLS} each and {MIN_TIMED_SECONDS} s each); the best call of each is reported")

    # --- NumPy baseline: sanity check against marinejax, then throughput -------------------------
    npv = NumpyVehicle(vehicle, physics_dt, args.integrator)
    rng = np.random.default_rng(0)
    sanity_steps = max(1, round(SANITY_SECONDS / args.control_dt))
    sanity_cmd = rng.uniform(-0.3, 0.3, (sanity_steps, vehicle.num_actuators))
    traj = marinejax.rollout(vehicle, jnp.asarray(sanity_cmd, jnp.float32), control_dt=args.control_dt,
                             substeps=args.substeps, integrator=args.integrator)
    ref = np.asarray(traj.position, dtype=np.float64)
    mine = npv.rollout(sanity_cmd, args.substeps)
    diff = float(np.max(np.abs(ref - mine)))
    travelled = float(np.max(np.linalg.norm(ref, axis=-1)))
    console.print(f"NumPy baseline vs marinejax: max position difference {diff:.2e} m "
                  f"(one vehicle, {sanity_steps * args.control_dt:g} s, {travelled:.3f} m from the start at most)")
    sanity_ok = diff <= SANITY_TOLERANCE_M
    if not sanity_ok:
        console.print(f"[red]warning: the NumPy baseline disagrees with marinejax by more than {SANITY_TOLERANCE_M} m[/red]")

    np_throttles = rng.uniform(-0.3, 0.3, (16, args.steps, vehicle.num_actuators))
    npres = time_numpy(npv, np_throttles, args.substeps, args.numpy_seconds)
    numpy_rate = npres["vehicle_steps_per_s"]
    numpy_rtf = numpy_rate * physics_dt
    console.print(f"NumPy baseline: {npres['vehicles']} vehicles x {args.steps} control steps x {args.substeps} substeps "
                  f"in {npres['seconds']:.2f} s -> {numpy_rate:,.0f} vehicle-steps/s, real-time factor {numpy_rtf:.1f} "
                  f"({1e6 / numpy_rate:.1f} us per physics step)")

    # --- batched JAX --------------------------------------------------------------------------
    rows = []
    for batch in args.batch_sizes:
        steps = min(args.steps, max(1, MAX_VEHICLE_CONTROL_STEPS // batch))
        res = time_batch(vehicle, batch, steps, args.control_dt, args.substeps, args.integrator)
        full_s, bare_s = res["full"]["seconds"], res["bare"]["seconds"]
        work = batch * steps * args.substeps
        sim = batch * steps * args.control_dt
        row = {
            "batch": batch,
            "steps": steps,
            "steps_reduced": steps < args.steps,
            "full_seconds": full_s,
            "full_vehicle_steps_per_s": work / full_s,
            "full_rtf": sim / full_s,
            "full_compile_seconds": res["full"]["compile_seconds"],
            "full_calls": res["full"]["calls"],
            "bare_seconds": bare_s,
            "bare_vehicle_steps_per_s": work / bare_s,
            "bare_rtf": sim / bare_s,
            "bare_compile_seconds": res["bare"]["compile_seconds"],
            "bare_calls": res["bare"]["calls"],
            "hydro_overhead": full_s / bare_s - 1.0,
            "speedup_vs_numpy": (work / full_s) / numpy_rate,
            "finite": res["finite"],
        }
        rows.append(row)
        console.print(f"  batch {batch:>6}: full {full_s:.4f} s (best of {row['full_calls']}, compile "
                      f"{row['full_compile_seconds']:.1f} s), bare {bare_s:.4f} s (best of {row['bare_calls']}, "
                      f"compile {row['bare_compile_seconds']:.1f} s)")
        if not res["finite"]:
            console.print(f"[red]warning: batch {batch} produced non-finite states[/red]")

    _print_table(console, rows, numpy_rate, numpy_rtf)
    if any(r["steps_reduced"] for r in rows):
        console.print(f"* control steps reduced from {args.steps} so that batch x steps <= {MAX_VEHICLE_CONTROL_STEPS}")
    console.print("hydro overhead = full time / bare MJX time - 1; speedup = full vehicle-steps/s / NumPy vehicle-steps/s")

    verdicts = {}
    target = next((r for r in rows if r["batch"] == TARGET_BATCH), None)
    if target is not None:
        verdicts["speedup_at_4096"] = target["speedup_vs_numpy"] >= TARGET_SPEEDUP
        verdicts["overhead_at_4096"] = target["hydro_overhead"] <= TARGET_OVERHEAD
        console.print(f"target, batch {TARGET_BATCH}: speedup over NumPy {target['speedup_vs_numpy']:.1f}x "
                      f"(>= {TARGET_SPEEDUP:g}x: {'met' if verdicts['speedup_at_4096'] else 'NOT met'}); "
                      f"hydro overhead {100 * target['hydro_overhead']:+.1f} % "
                      f"(<= {100 * TARGET_OVERHEAD:g} %: {'met' if verdicts['overhead_at_4096'] else 'NOT met'})")
    total = time.perf_counter() - total_start
    console.print(f"total benchmark time {total:.0f} s")

    if args.out is not None:
        result = {
            "machine": info,
            "settings": {"vehicle": vehicle.name, "param_set": vehicle.param_set, "batch_sizes": args.batch_sizes,
                         "steps": args.steps, "control_dt": args.control_dt, "substeps": args.substeps,
                         "integrator": args.integrator,
                         "physics_dt": physics_dt, "numpy_seconds": args.numpy_seconds,
                         "max_vehicle_control_steps": MAX_VEHICLE_CONTROL_STEPS},
            "numpy": {**npres, "real_time_factor": numpy_rtf},
            "numpy_vs_marinejax_max_position_difference_m": diff,
            "rows": rows,
            "targets": verdicts,
            "total_seconds": total,
        }
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(result, indent=2) + "\n")
        console.print(f"wrote {args.out}")
    return 0 if sanity_ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
