"""The `marinejax` command line.

    marinejax train ENV [--timesteps N] [--seed S] [--target-error M] [--ppo KEY=VALUE ...] [--env KEY=VALUE ...]
    marinejax train --resume RUN_DIR
    marinejax eval RUN_DIR_OR_CHECKPOINT [--checkpoint best|latest] [--episodes N] [--env KEY=VALUE ...]
    marinejax validate [--vehicle NAME] [--param-set SET] [--dt S]
    marinejax bench physics|envs|training|clients [flags]

Every command keeps JAX's persistent compilation cache in the user's cache directory
(`$XDG_CACHE_HOME/marinejax/jax-compilation-cache`, else `~/.cache/...`), and training keeps the
training env's traced reset and step beside it (`.../marinejax/traced-envs`, `envs/trace_cache.py`),
so that a second identical run skips most of its tracing and compilation; `--no-compile-cache`
switches both off for one command.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
import warnings
from pathlib import Path
from typing import Any

from marinejax.config import parse_key_values
from marinejax.errors import UserError


def compile_cache_dir() -> Path:
    """Where the CLI keeps JAX's persistent compilation cache: `$XDG_CACHE_HOME` or `~/.cache`, then
    `marinejax/jax-compilation-cache`."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "marinejax" / "jax-compilation-cache"


def trace_cache_dir() -> Path:
    """Where the CLI keeps the training env's traced reset and step (`envs/trace_cache.py`), beside
    the compilation cache: `.../marinejax/traced-envs`."""
    return compile_cache_dir().parent / "traced-envs"


def enable_compile_cache(path: Path) -> None:
    """Turn on JAX's persistent compilation cache in `path` for this process, for every compiled
    function (JAX's default skips those that compile in under a second, which is most of an env)."""
    import jax

    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


# Packages whose deprecation notices are about their own internals: a CLI user cannot act on them.
_DEPENDENCIES = ("brax", "flax", "orbax", "jaxopt", "jax", "jaxlib", "mujoco", "optax", "chex", "etils")


def quiet_dependency_warnings() -> None:
    """Hide DeprecationWarning and FutureWarning raised from inside dependencies (CLI only; the
    library itself changes no warning filters)."""
    for package in _DEPENDENCIES:
        for category in (DeprecationWarning, FutureWarning):
            warnings.filterwarnings("ignore", category=category, module=rf"{package}(\.|$)")


def _validate(args: argparse.Namespace) -> int:
    from marinejax.validation import print_validation
    from marinejax.vehicle import load_vehicle

    if not (0 < args.dt <= 0.05):
        raise UserError(f"--dt must be in (0, 0.05] s, got {args.dt}")
    vehicle = load_vehicle(args.vehicle, param_set=args.param_set)
    rows = print_validation(vehicle, dt=args.dt)
    worst = max(abs(m - e) / abs(e) for _, m, e, _ in rows)
    print(f"largest relative difference: {100 * worst:.2f} %")
    return 0 if worst < 0.03 else 1


def _check_target(value: float | None) -> float | None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise UserError(f"--target-error must be a positive number of metres, got {value}")
    return value


def _train(args: argparse.Namespace) -> int:
    import jax

    from marinejax.console import make_console
    from marinejax.train.hyperparams import tuned_config, with_overrides
    from marinejax.train.progress import TrainingProgress
    from marinejax.train.hyperparams import load_train_config
    from marinejax.train.runner import check_devices, check_resumable, train_and_evaluate, use_cpu_devices

    console = make_console()
    target = _check_target(args.target_error)
    _initialize_processes(args)  # before anything starts JAX's backend
    if args.wandb is not None:
        from marinejax.train import wandb_log

        wandb_log.check(args.wandb)
    if args.resume:
        if args.env_name or args.ppo or args.algo or args.algo_opts or args.env or args.timesteps or args.run_dir or args.randomize:
            raise UserError("--resume takes only the run directory: the run's own settings are reused")
        run_dir = Path(args.resume)
        if not (run_dir / "config.json").exists():
            raise UserError(f"--resume: {run_dir} is not a run directory (no config.json)")
        config = load_train_config(run_dir)
        check_resumable(config, run_dir)
    else:
        if not args.env_name:
            raise UserError("name the env to train, e.g. `marinejax train BlueROV2Heavy-StationKeeping` (or --resume RUN_DIR)")
        agent = parse_key_values(args.algo_opts, "--algo-opts")
        if args.timesteps is not None:
            agent["num_timesteps"] = args.timesteps
        if args.seed is not None:
            agent["seed"] = args.seed
        env_overrides = parse_key_values(args.env, "--env")
        if args.randomize:
            env_overrides["randomization.enabled"] = True
        config = with_overrides(tuned_config(args.env_name, args.algo or "ppo"), ppo=parse_key_values(args.ppo, "--ppo"),
                                agent=agent, env=env_overrides)
    use_cpu_devices(args.devices or config.agent.cpu_devices)  # before anything starts JAX's backend
    if not args.resume:
        from marinejax.train.hyperparams import build_env

        build_env(config)  # validate the env overrides before creating a run directory
        run_dir = Path(args.run_dir) if args.run_dir else Path("runs") / f"{config.env}-{time.strftime('%Y%m%d-%H%M%S')}"
        if (run_dir / "config.json").exists():
            raise UserError(f"{run_dir} already holds a run; use --resume {run_dir} to continue it")
    devices = check_devices(args.devices, config.agent)
    processes = f" × {jax.process_count()} processes" if jax.process_count() > 1 else ""
    console.print(f"[bold]marinejax train[/bold] {config.env} → {run_dir}  ({config.algorithm.upper()}, "
                  f"{config.agent.num_timesteps:,} env steps, {config.agent.num_envs} envs on {devices} {jax.default_backend()} "
                  f"device(s){processes}; compiling takes about a minute)")
    if jax.process_count() > 1:
        # Connect the processes' collectives now, after every process has checked the run directory
        # and before process 0 writes it: Gloo gives up after 30 s when one process reaches its first
        # collective that much before another (in Brax, process 0 first evaluates the initial policy).
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices("marinejax train")

    def on_trained(summary: dict) -> None:
        progress.stop()
        if jax.process_index() > 0:
            return
        if summary.get("time_to_target"):
            t = summary["time_to_target"]
            console.print(f"target {target} m met at {t['step']:,} env steps, {t['elapsed']:.0f} s "
                          f"(evaluation error {t['window_error']:.4f} m); training stopped there")
        from marinejax.train.curves import plot_learning_curve

        plot_learning_curve(run_dir)
        if jax.process_count() > 1 and not args.no_eval:
            console.print(f"several processes: evaluate the run in one process, `marinejax eval {run_dir}`")
        elif not args.no_eval:
            console.print("final evaluation (deterministic policy) ...")

    with TrainingProgress(console, config) as progress:
        try:
            _summary, evaluation = train_and_evaluate(
                config, run_dir, evaluate=not args.no_eval, episodes=args.episodes, video=not args.no_video,
                on_trained=on_trained, resume=bool(args.resume), on_eval=progress.update, target_error=target,
                devices=args.devices, trace_cache=None if args.no_compile_cache else trace_cache_dir(),
                wandb_project=args.wandb)
        except KeyboardInterrupt:
            console.print(f"[yellow]interrupted[/yellow]: the newest checkpoint in {run_dir}/checkpoints is usable; "
                          f"continue with `marinejax train --resume {run_dir}`")
            return 130
    if jax.process_index() > 0:
        console.print(f"process {jax.process_index()} of {jax.process_count()}: done; process 0 wrote {run_dir}")
        return 0
    if evaluation is not None:
        _print_eval(console, evaluation)
    console.print(f"run directory: {run_dir} (config.json, metrics.jsonl, checkpoints/, curve.png, summary.json, eval/)")
    return 0


def _initialize_processes(args: argparse.Namespace) -> None:
    """`jax.distributed.initialize` from --coordinator, --num-processes and --process-id (all or
    none); on CPUs the processes' collectives go through Gloo."""
    given = [args.coordinator is not None, args.num_processes is not None, args.process_id is not None]
    if not any(given):
        return
    if not all(given):
        raise UserError("training with several processes needs --coordinator HOST:PORT, --num-processes N and --process-id I together")
    host, _, port = args.coordinator.rpartition(":")
    if not host or not port.isdigit():
        raise UserError(f"--coordinator must be HOST:PORT (e.g. 10.0.0.1:1234), got {args.coordinator!r}")
    if args.num_processes < 1 or not 0 <= args.process_id < args.num_processes:
        raise UserError(f"--process-id must be in 0..{args.num_processes - 1} and --num-processes >= 1, "
                        f"got {args.process_id} of {args.num_processes}")
    import jax

    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(args.coordinator, num_processes=args.num_processes, process_id=args.process_id)


def _print_eval(console, result: dict[str, Any]) -> None:
    console.print(
        f"{result['env']}: {result['episodes']} episodes, position error ({result['window']}): "
        f"mean {result['position_error_mean_m']:.4f} m, median {result['position_error_median_m']:.4f} m, "
        f"95th percentile {result['position_error_p95_m']:.4f} m; success rate ("
        + (f"{result['success_flag']} at the end" if result.get("success_flag") else f"< {result['success_threshold_m']} m"
           + (f" and < {result['success_heading_deg']:g}°" if result.get("success_heading_deg") is not None else "")) + ") "
        f"{100 * result['success_rate']:.0f} %"
    )
    others = [f"{key.replace('_mean', '').removesuffix('_deg').replace('_', ' ')} "
              + (f"{result[key]:.2f}°" if unit == "°" else f"{result[key]:.4f} {unit}".rstrip())
              for key, unit in result.get("units", {}).items()]
    if others:
        console.print(f"  mean over the window: {', '.join(others)}")
    if "checkpoint" in result:
        console.print(f"  checkpoint: {result['checkpoint']} ({result['checkpoint_kind']})")
    else:
        gains = f", gains {result['gains']}" if "gains" in result else ""
        console.print(f"  controller: {result['controller']} {result['config']}{gains} (tuned on seed {result['tuning']['seed']})")
    for key in ("plot", "video", "video_error"):
        if key in result:
            console.print(f"  {key.replace('_', ' ')}: {result[key]}")


def _eval(args: argparse.Namespace) -> int:
    from marinejax.console import make_console
    from marinejax.train.evaluate import evaluate_run

    overrides = parse_key_values(args.env, "--env")
    if args.randomize:
        overrides["randomization.enabled"] = True
    if args.current:
        overrides["current.mode"] = args.current
    if args.episodes < 1:
        raise UserError(f"--episodes must be >= 1, got {args.episodes}")
    console = make_console()
    if args.controller:
        from marinejax.train.evaluate import evaluate_controller

        result = evaluate_controller(args.path, args.controller, out_dir=args.out, episodes=args.episodes, seed=args.seed,
                                     env_overrides=overrides, video=not args.no_video, progress=console.print)
    else:
        result = evaluate_run(Path(args.path), out_dir=args.out, episodes=args.episodes, seed=args.seed,
                              env_overrides=overrides, video=not args.no_video, which=args.checkpoint)
    _print_eval(console, result)
    return 0


def _export(args: argparse.Namespace) -> int:
    from marinejax.export import export_policy

    path = export_policy(args.path, args.format, Path(args.out) if args.out else None, args.checkpoint)
    print(f"wrote {path} ({args.format}); metadata inside: env, observation layout, action meaning, control rate")
    return 0


def _excite(args: argparse.Namespace) -> int:
    import numpy as np

    from marinejax.identify import Log, excitation, write_log
    from marinejax.plant import Plant, PlantConfig

    plant = Plant(args.vehicle, PlantConfig())
    commands = excitation(plant, args.duration, args.amplitude, args.seed)
    path = write_log(args.out, Log(time=plant.config.control_dt * np.arange(len(commands)), commands=commands))
    print(f"wrote {path}: {len(commands)} commands at {1 / plant.config.control_dt:g} Hz for {args.vehicle} "
          f"({plant.vehicle.num_actuators} thrusters, throttles in [-1, 1]); run them, log the state columns, then `marinejax identify`")
    return 0


def _identify(args: argparse.Namespace) -> int:
    from marinejax.errors import MissingFileError
    from marinejax.identify import Identifier, plot_fit, read_log, save_param_set
    from marinejax.plant import Plant, PlantConfig
    from marinejax.vehicle import list_vehicles

    if not Path(args.log).is_file():  # checked before anything compiles
        raise MissingFileError(f"log file not found: {args.log}")
    if args.vehicle not in list_vehicles():
        raise UserError(f"unknown vehicle {args.vehicle!r}; available vehicles: {list_vehicles()}")
    plant = Plant(args.vehicle, PlantConfig())
    log = read_log(args.log, plant.vehicle.num_actuators)
    ident = Identifier(plant, log, args.window, fit_thruster_gain=args.fit_thruster_gain)
    print(f"{args.log}: {len(log.time)} rows, {len(log.time) * log.dt:.0f} s, {ident.start.velocity.shape[0]} windows of {ident.steps} steps; "
          "fitting (the first iteration compiles) ...")
    result = ident.fit(progress=print)
    print(f"cost (mean squared residual / noise^2): {result.cost_before:.4g} -> {result.cost_after:.4g} in {result.seconds:.0f} s")
    if result.warning:
        print(f"warning: {result.warning}; the values below are the fit's last iterate")
    print(f"{'parameter':24s} {'default':>10s} {'fitted':>10s} {'std':>9s}")
    for name, x0, v, sd, det, fit in zip(result.names, result.initial, result.values, result.std, result.determined, result.fitted):
        note = "held (not fitted)" if not fit else ("" if det else "not determined by this log")
        print(f"{name:24s} {x0:10.4g} {v:10.4g} {sd:9.2g}  {note}")
    out = Path(args.out) if args.out else Path(args.log).with_name(Path(args.log).stem + "-params.json")
    save_param_set(out, args.vehicle, result, source=f"identified from {Path(args.log).name} by marinejax identify")
    plot = plot_fit(ident, result, out.with_suffix(".png"))
    print(f"wrote {out} (use: marinejax train ENV --env param_set={out}) and {plot} (logged vs simulated, before and after)")
    return 0


def _bench(args: argparse.Namespace, rest: list[str]) -> int:
    if args.what == "physics":
        from marinejax.benchmarks.physics import main as bench_main
    elif args.what == "envs":
        from marinejax.benchmarks.envs import main as bench_main
    elif args.what == "clients":
        from marinejax.benchmarks.clients import main as bench_main
    else:
        from marinejax.benchmarks.training import main as bench_main

        return bench_main(rest, trace_cache=None if args.no_compile_cache else trace_cache_dir())
    return bench_main(rest)


def _list(args: argparse.Namespace) -> int:
    """What exists: vehicles (with kind and actuators), scenes, tasks (with the kinds they are for),
    envs, classical controllers and shipped policies."""
    from marinejax.controllers import CONTROLLERS
    from marinejax.envs import list_envs
    from marinejax.envs.registry import list_tasks
    from marinejax.train.checkpoints import shipped_policies
    from marinejax.vehicle import list_vehicles, load_vehicle, vehicle_kind

    what = args.what
    if what in ("all", "vehicles"):
        print("vehicles (marinejax validate --vehicle NAME):")
        for name in list_vehicles():
            v = load_vehicle(name)
            print(f"  {name:<20} {vehicle_kind(name):<8} {v.num_actuators} actuators: {', '.join(v.actuator_names)}")
    if what in ("all", "scenes"):
        from marinejax.scene import list_scenes

        print(f"scenes (marinejax train ENV --env scene=NAME): {', '.join(list_scenes())}")
    if what in ("all", "tasks"):
        print("tasks (<Vehicle>-<Task>; each also <Task>Disturbed):")
        for task, kinds in list_tasks().items():
            if not task.endswith("Disturbed"):
                print(f"  {task:<24} for {', '.join(kinds)}")
    if what in ("all", "envs"):
        print("envs (marinejax train NAME):")
        for name in list_envs():
            print(f"  {name}")
    if what in ("all", "controllers"):
        print(f"classical controllers (marinejax eval ENV --controller NAME): {', '.join(CONTROLLERS)}")
    if what in ("all", "policies"):
        print(f"shipped policies (marinejax eval NAME): {', '.join(shipped_policies()) or 'none'}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="marinejax", description="Underwater vehicles in JAX + MuJoCo MJX.")
    sub = parser.add_subparsers(dest="command", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--no-compile-cache", action="store_true",
                        help=f"do not use JAX's persistent compilation cache (default: on, in {compile_cache_dir()}) "
                             f"nor keep the envs' traced functions (in {trace_cache_dir()})")

    tr = sub.add_parser("train", parents=[common], help="train an env with PPO (tuned defaults per task)")
    tr.add_argument("env_name", nargs="?", help="env name, e.g. BlueROV2Heavy-StationKeeping (see marinejax.list_envs())")
    tr.add_argument("--resume", metavar="RUN_DIR", help="continue an interrupted run from its newest checkpoint")
    tr.add_argument("--run-dir", help="where to write the run (default runs/<ENV>-<time>)")
    tr.add_argument("--timesteps", type=int, help="total env steps (overrides the tuned num_timesteps)")
    tr.add_argument("--seed", type=int, help="random seed")
    tr.add_argument("--target-error", type=float, metavar="METRES",
                    help="stop once the evaluation error (the task's window, as in `marinejax eval`) is at most this")
    tr.add_argument("--algo", choices=["ppo", "sac"], help="training algorithm (default ppo)")
    tr.add_argument("--algo-opts", action="append", metavar="KEY=VALUE",
                    help="override a setting of the algorithm, e.g. --algo-opts learning_rate=1e-3 (PPOConfig, SACConfig)")
    tr.add_argument("--ppo", action="append", metavar="KEY=VALUE", help="override a PPO setting, e.g. --ppo learning_rate=1e-3")
    tr.add_argument("--env", action="append", metavar="KEY=VALUE", help="override an env setting, e.g. --env reward.effort=0.1")
    tr.add_argument("--devices", type=int, metavar="N",
                    help="train on N devices, the env batch split over them: on a CPU host the cores split into N JAX "
                         "devices (default: the recipe's cpu_devices), on GPUs the first N (default: all)")
    tr.add_argument("--coordinator", metavar="HOST:PORT",
                    help="train with several processes (hosts): the address of process 0, reachable from every process; "
                         "with --num-processes and --process-id (jax.distributed.initialize)")
    tr.add_argument("--num-processes", type=int, metavar="N", help="the number of processes training together (--coordinator)")
    tr.add_argument("--process-id", type=int, metavar="I", help="this process's index, 0..N-1 (--coordinator); process 0 writes the run")
    tr.add_argument("--randomize", action="store_true", help="per-episode domain randomization (sets --env randomization.enabled=true)")
    tr.add_argument("--episodes", type=int, default=64, help="episodes of the final evaluation (default 64)")
    tr.add_argument("--no-eval", action="store_true", help="skip the final evaluation")
    tr.add_argument("--no-video", action="store_true", help="skip the video of the final evaluation")
    tr.add_argument("--wandb", metavar="PROJECT", help="also log every evaluation to this Weights & Biases project "
                    "(needs `pip install wandb`; a resumed run continues its W&B run)")

    ev = sub.add_parser("eval", parents=[common], help="evaluate a run directory, checkpoint or classical controller: statistics, path plot, video")
    ev.add_argument("path", help="run directory (its best checkpoint), a checkpoint directory, or with --controller an env name")
    ev.add_argument("--controller", choices=["pid", "lqr", "autopilot", "los", "terrain", "avoid"], help="evaluate this classical controller (tuned first) on the env PATH instead of a policy")
    ev.add_argument("--checkpoint", choices=["best", "latest"], default="best",
                    help="for a run directory: the checkpoint with the lowest evaluation error during training, or with "
                         "best_on=targets the nearest to meeting every target (default), or the newest")
    ev.add_argument("--episodes", type=int, default=64, help="number of episodes (default 64)")
    ev.add_argument("--seed", type=int, default=12345, help="seed of the evaluation episodes")
    ev.add_argument("--env", action="append", metavar="KEY=VALUE", help="override an env setting for the evaluation")
    ev.add_argument("--randomize", action="store_true", help="per-episode domain randomization (sets --env randomization.enabled=true)")
    ev.add_argument("--current", choices=["off", "constant", "ou"], help="evaluate in an ocean current")
    ev.add_argument("--out", type=Path, help="output directory (default RUN_DIR/eval)")
    ev.add_argument("--no-video", action="store_true", help="skip the video")

    val = sub.add_parser("validate", parents=[common], help="simulate force steps and a roll swing; print them against closed-form values")
    val.add_argument("--vehicle", default="bluerov2_heavy", help="vehicle name (see marinejax.list_vehicles())")
    val.add_argument("--param-set", default=None, help="named parameter set of the vehicle (default: the vehicle's default)")
    val.add_argument("--dt", type=float, default=0.05,
                     help="physics step in seconds, midpoint integrator (default 0.05, the env default)")

    ex = sub.add_parser("export", parents=[common], help="write a trained policy as ONNX or as NumPy weights (npz) for deployment")
    ex.add_argument("path", help="run directory, checkpoint directory, or the env name of a shipped policy")
    ex.add_argument("--format", choices=["onnx", "npz"], default="onnx",
                    help="onnx (needs pip install 'marinejax[export]') or npz (marinejax.export.load_numpy_policy, NumPy only)")
    ex.add_argument("--out", help="output file (default ./<env>-policy.<format>)")
    ex.add_argument("--checkpoint", choices=["best", "latest"], default="best", help="for a run directory: which checkpoint")

    exc = sub.add_parser("excite", parents=[common], help="write an excitation command sequence (CSV log format) to run on a vehicle for identification")
    exc.add_argument("vehicle", help="vehicle name (see marinejax.list_vehicles())")
    exc.add_argument("--out", required=True, help="CSV file to write (time_s, u1..uN)")
    exc.add_argument("--duration", type=float, default=120.0, help="seconds (default 120)")
    exc.add_argument("--amplitude", type=float, default=0.5, help="fraction of full thrust per thruster, in (0, 1] (default 0.5)")
    exc.add_argument("--seed", type=int, default=0)

    idf = sub.add_parser("identify", parents=[common], help="fit a vehicle's fluid and thruster parameters to a logged run")
    idf.add_argument("log", help="CSV log (see marinejax.identify for the columns)")
    idf.add_argument("--vehicle", required=True, help="vehicle name whose parameters are the starting point")
    idf.add_argument("--out", default=None, help="parameter-set JSON to write (default <log>-params.json), usable as --env param_set=PATH")
    idf.add_argument("--window", type=float, default=1.0, help="seconds per multiple-shooting window (default 1; the fit first runs on windows of half that)")
    idf.add_argument("--fit-thruster-gain", action="store_true", help="also fit the thruster gain (not separable from the masses; see the docs)")

    ls = sub.add_parser("list", parents=[common], help="what exists: vehicles, tasks, envs, controllers, shipped policies")
    ls.add_argument("what", nargs="?", default="all", choices=["all", "vehicles", "scenes", "tasks", "envs", "controllers", "policies"])

    bench = sub.add_parser("bench", add_help=False, parents=[common],
                           help="benchmarks: `marinejax bench physics|envs|training|clients [flags]` (-h for their flags)")
    bench.add_argument("what", choices=["physics", "envs", "training", "clients"])
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, rest = parser.parse_known_args(argv)
    if args.command != "bench" and rest:
        parser.error(f"unrecognized arguments: {' '.join(rest)}")
    quiet_dependency_warnings()
    if not args.no_compile_cache:
        enable_compile_cache(compile_cache_dir())
    try:
        if args.command == "train":
            return _train(args)
        if args.command == "eval":
            return _eval(args)
        if args.command == "validate":
            return _validate(args)
        if args.command == "export":
            return _export(args)
        if args.command == "excite":
            return _excite(args)
        if args.command == "identify":
            return _identify(args)
        if args.command == "list":
            return _list(args)
        return _bench(args, rest)
    except UserError as err:  # anything else is a bug: let its traceback show
        print(f"marinejax {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
