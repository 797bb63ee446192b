"""The `ftdrake` command: simulate | collect | study | train | evaluate | demo | serve | record."""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import sys
from pathlib import Path

from ..config import ScenarioConfig, load_config
from ..errors import ConfigError, FtdrakeError, ModelFileError


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="ftdrake", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    _add_simulate(sub)
    _add_collect(sub)
    _add_demo(sub)
    _add_export(sub)
    _add_evaluate_detection(sub)
    from . import calibrate, hardware, study, train

    study.register(sub)
    train.register(sub)
    calibrate.register(sub)
    hardware.register(sub)
    from . import feedforward, replay

    feedforward.register(sub)
    replay.register(sub)
    return run(parser.parse_args(argv))


def run(args) -> int:
    """Runs a parsed command. A :class:`FtdrakeError` (a problem the user can fix: its message
    names the flag or field) prints as ``ftdrake CMD: error: MESSAGE`` and exits with 2, like
    argparse's own errors. Any other exception is a bug in ftdrake and keeps its traceback."""
    try:
        return args.run(args) or 0
    except FtdrakeError as e:
        print(f"ftdrake {args.command}: error: {_naming_the_flag(e, args)}", file=sys.stderr)
        return 2


# Scenario fields that a command's flag sets (`--duration` overrides the file's duration_s).
_FIELD_FLAGS = {"trajectory.duration_s": "--duration"}


def _naming_the_flag(error: FtdrakeError, args) -> str:
    """The message of `error`, reworded to name the flag that sets the field it is about: the
    field's own flag if one was given, else --config for a scenario field (``scenario.x``)."""
    message = str(error)
    for field, flag in _FIELD_FLAGS.items():
        value = getattr(args, flag.removeprefix("--").replace("-", "_"), None)
        found = re.match(rf"(scenario\.)?{re.escape(field)}: ", message)
        if value is not None and found:
            return f"{flag} {value}: {message[found.end():]}"
    config = getattr(args, "config", None)
    if isinstance(error, ConfigError) and config is not None and message.startswith("scenario."):
        return f"--config {config}: {message}"
    return message


@contextlib.contextmanager
def naming(flag: str, value):
    """Prefixes the message of a FtdrakeError raised inside with the flag that set `value`, so
    ``x.yaml: sensor.rate_hz ...`` reads ``--config x.yaml: sensor.rate_hz ...``."""
    try:
        yield
    except FtdrakeError as e:
        message = str(e)
        for prefix in (f"{value}: ", f"{value} "):
            message = message.removeprefix(prefix)
        raise type(e)(f"{flag} {value}: {message}") from None


def existing_file(flag: str, path: Path | None, kind: type[FtdrakeError] = FtdrakeError):
    """`path` unless it is given and is not a file: then a `kind` error naming `flag`."""
    if path is not None and not Path(path).is_file():
        what = "a folder, not a file" if Path(path).is_dir() else "no such file"
        raise kind(f"{flag} {path}: {what}")
    return path


def output_path(flag: str, path: Path, *, folder: bool) -> Path:
    """Checks, before a long run, that `path` can be written: a folder (`folder`) or a file,
    below a folder (created as needed). Raises a FtdrakeError naming `flag` otherwise."""
    path = Path(path)
    if path.exists() and path.is_dir() != folder:
        raise FtdrakeError(f"{flag} {path}: is a {'file' if folder else 'folder'}; "
                           f"give a {'folder' if folder else 'file'} name")
    parent = path.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise FtdrakeError(f"{flag} {path}: {parent} is a file, not a folder")
    return path


def load_scenario(args) -> ScenarioConfig:
    """The scenario of --config (the shipped one without it); errors name --config."""
    if args.config is None:
        return load_config(None)
    existing_file("--config", args.config, ConfigError)
    with naming("--config", args.config):
        return load_config(args.config)


def scenario_from_args(args, kind: str | None = None) -> ScenarioConfig:
    """Loads --config and applies --duration/--seed overrides common to commands."""
    config = load_scenario(args)
    if kind is not None:
        config.trajectory.kind = kind
    if getattr(args, "duration", None) is not None:
        config.trajectory.duration_s = args.duration
    if getattr(args, "seed", None) is not None:
        config.trajectory.seed = args.seed
        config.sensor.seed = args.seed
    return config.validate()


# Argument types: argparse reports a bad value as `ftdrake CMD: error: argument --FLAG: ...`
# (exit code 2) before anything runs.
def _number(parse, accept, requirement: str):
    def convert(text: str):
        try:
            value = parse(text)
        except ValueError:
            value = None
        if value is None or not accept(value):
            raise argparse.ArgumentTypeError(f"{requirement}; got {text!r}")
        return value

    return convert


positive_int = _number(int, lambda v: v >= 1, "must be a whole number >= 1")
positive_float = _number(float, lambda v: 0 < v < float("inf"), "must be a positive number")
seed = _number(int, lambda v: 0 <= v < 2**32, "must be a whole number in [0, 2**32)")
jobs = _number(int, lambda v: v != 0, "must be a number of processes, or -1 for all cores")


# ----------------------------------------------------------------------------------------------
def _add_simulate(sub):
    p = sub.add_parser("simulate", help="run the diagram once; write log, figure and summary")
    p.add_argument("--config", type=Path, help="scenario YAML (default: the shipped one)")
    p.add_argument("--scenario", choices=["free", "contact"], default="contact")
    p.add_argument("--duration", type=positive_float, help="seconds to simulate")
    p.add_argument("--seed", type=seed, help="seed of trajectory and sensor noise")
    p.add_argument("--out", type=Path, default=Path("out/simulate"))
    p.add_argument("--meshcat-html", action="store_true", help="also write replay.html")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--lcm", metavar="URL", help="also publish the arm's joint state and the "
                   "sensor on LCM, on the channels of --hardware (see `ftdrake serve`)")
    p.add_argument("--hardware", type=Path, metavar="FILE", help="HardwareConfig YAML "
                   "(channels, message types) for --lcm")
    p.add_argument("--realtime", action="store_true", help="pace the simulation to the wall "
                   "clock")
    p.set_defaults(run=_simulate)


def _simulate(args):
    from ..io import atomic_path, staged_outputs
    from ..plots import plot_wrench_log
    from ..sim.simulate import simulate
    from ..sim.station import build_station

    config = scenario_from_args(args, "fourier" if args.scenario == "free" else "contact")
    output_path("--out", args.out, folder=True)
    meshcat = _meshcat() if args.meshcat_html else None
    station = build_station(config, meshcat=meshcat)
    if meshcat is not None:
        meshcat.StartRecording(set_visualizations_while_recording=False)
    if args.lcm is not None or args.hardware is not None:
        from ..sim.lcm_publisher import simulate_on_lcm
        from .hardware import describe_channels, hardware_from_args, open_transport

        hardware = hardware_from_args(args)
        print(f"ftdrake simulate: publishing {describe_channels(hardware).splitlines()[1]}"
              f" on {hardware.lcm_url}".replace("  in:  ", ""), file=sys.stderr, flush=True)
        result = simulate_on_lcm(station, hardware, open_transport(args, hardware),
                                 realtime_rate=1.0 if args.realtime else 0.0,
                                 progress=not args.quiet)
    else:
        result = simulate(station, progress=not args.quiet,
                          realtime_rate=1.0 if args.realtime else 0.0)
    log, summary = result.log, dict(result.timing)
    contact_times = log.loc[log["contact"] == 1, "t"]
    summary.update(
        scenario=args.scenario,
        trajectory=config.trajectory.kind,
        sensor_preset=config.sensor.preset,
        sensor_rate_hz=config.sensor.spec().rate_hz,
        first_contact_time_s=float(contact_times.iloc[0]) if len(contact_times) else None,
        max_contact_force_n=float(
            (log[["external_Fx", "external_Fy", "external_Fz"]] ** 2).sum(axis=1).max() ** 0.5
        ),
        saturated_samples=int(log["saturated"].sum()),
    )
    with staged_outputs(args.out) as stage:
        log.to_parquet(stage / "log.parquet", index=False)
        plot_wrench_log(log, stage / "wrench.png", title=f"{args.scenario} scenario")
        if meshcat is not None:
            meshcat.StopRecording()
            meshcat.PublishRecording()
            (stage / "replay.html").write_text(meshcat.StaticHtml())
        with atomic_path(stage / "summary.json") as tmp:
            tmp.write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    return 0


def _add_collect(sub):
    p = sub.add_parser("collect", help="free-motion runs → one Parquet dataset")
    p.add_argument("--config", type=Path, help="scenario YAML (default: the shipped one)")
    p.add_argument("--trajectories", type=positive_int, default=8)
    p.add_argument("--duration", type=positive_float, default=20.0, help="seconds per trajectory")
    p.add_argument("--kind", choices=["random", "fourier", "reference", "z_rich", "rehearsal"],
                   default="fourier",
                   help="rehearsal: the contact scenario stopping 3 cm above the surface")
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--jobs", type=jobs, default=-1, help="local worker processes (-1: all cores)")
    p.add_argument("--dask", metavar="ADDRESS", help="run on this Dask scheduler instead")
    p.add_argument("--out", type=Path, default=Path("out/dataset.parquet"))
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=_collect)


def _collect(args):
    from ..data.dataset import save_dataset
    from ..sim.collection import collect

    config = load_scenario(args)
    output_path("--out", args.out, folder=False)
    try:
        frame = collect(config, args.trajectories, seed=args.seed, kind=args.kind,
                        duration=args.duration, n_jobs=args.jobs, dask_address=args.dask,
                        progress=not args.quiet)
    except OSError as e:  # dask.distributed: the scheduler cannot be reached
        if args.dask is None:
            raise
        raise FtdrakeError(f"--dask {args.dask}: {e}") from e
    save_dataset(frame, args.out)
    print(json.dumps({"out": str(args.out), "rows": len(frame),
                      "trajectories": int(frame["trajectory"].nunique()),
                      "contact_rows": int(frame["contact"].sum())}))
    return 0


def _add_demo(sub):
    p = sub.add_parser("demo", help="collect → train → contact scenario in the loop (main job)")
    p.add_argument("--config", type=Path, help="scenario YAML (default: the shipped one)")
    p.add_argument("--out", type=Path, default=Path("out/demo"))
    p.add_argument("--trajectories", type=positive_int, default=4,
                   help="Fourier runs to train on")
    p.add_argument("--duration", type=positive_float, default=20.0,
                   help="seconds per training run")
    p.add_argument("--no-html", action="store_true", help="skip the Meshcat replay")
    p.add_argument("--rehearse-all-surfaces", action="store_true",
                   help="also train on (and hold out) one rehearsal at each other surface of "
                        "the task (the wall)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=_demo)


def _demo(args):
    from ..experiments.demo import print_table, run_demo

    config = load_scenario(args)
    output_path("--out", args.out, folder=True)
    summary = run_demo(args.out, config, fourier=args.trajectories, duration=args.duration,
                       other_surfaces=args.rehearse_all_surfaces,
                       meshcat_html=not args.no_html, progress=not args.quiet)
    print_table(summary)
    print(f"wrote {args.out}/summary.json, contact.png, model_forest.ftd, model_hybrid.ftd, "
          "contact_log_*.parquet" + ("" if args.no_html else ", replay.html"))
    return 0


def _add_export(sub):
    p = sub.add_parser("export", help="a saved compensator → ONNX (for controllers outside Python)")
    p.add_argument("--model", type=Path, required=True, help="a model file (train's --out)")
    p.add_argument("--out", type=Path, required=True, help="FILE.onnx")
    p.set_defaults(run=_export)


def _export(args):
    from ..compensation.base import Compensator
    from ..compensation.onnx_export import export_onnx
    from ..compensation.persistence import load_model

    existing_file("--model", args.model, ModelFileError)
    with naming("--model", args.model):
        model = load_model(args.model)
    if type(model).onnx_parts is Compensator.onnx_parts:  # the base class: no export
        raise ModelFileError(f"--model {args.model}: a {type(model).__name__} has no ONNX "
                             "export; forests (rf) and SVRs (svr) have one")
    output_path("--out", args.out, folder=False)
    path = export_onnx(model, args.out)
    print(json.dumps({"out": str(path), "input": f"X float64 (N x {3 * model.n_joints_}) "
                      "= [q, qd, qdd]", "output": f"float64 (N x {model.n_outputs_})"}))
    return 0


def _add_evaluate_detection(sub):
    p = sub.add_parser(
        "evaluate-detection",
        help="contact detection on unseen seeds: false positives in long free motion, misses "
             "and delays of presses on table and wall, a detection-rate plot")
    p.add_argument("--model", type=Path, action="append", required=True, metavar="MODEL",
                   help="a model file (repeat to compare models; named by file stem)")
    p.add_argument("--config", type=Path, help="scenario YAML (default: the shipped one)")
    p.add_argument("--minutes", type=positive_float, default=10.0,
                   help="simulated minutes of free motion, split over the trajectory kinds")
    p.add_argument("--budget", type=positive_float, default=1.0,
                   help="false positives per hour the thresholds are set for")
    p.add_argument("--jobs", type=jobs, default=-1, help="local worker processes (-1: all)")
    p.add_argument("--out", type=Path, default=Path("out/detection"))
    p.add_argument("--in-loop", action="store_true",
                   help="simulate every run with each model in the loop (default: simulate "
                        "each run once and replay every model over it; the same numbers)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=_evaluate_detection)


def _evaluate_detection(args):
    from ..compensation.persistence import load_model
    from ..experiments.detection import DetectionPlan, markdown, run_detection_evaluation

    config = load_scenario(args)
    models = {}
    for path in args.model:
        existing_file("--model", path, ModelFileError)
        with naming("--model", path):
            models[path.stem] = load_model(path, expect_n_joints=len(config.home_q))
    output_path("--out", args.out, folder=True)
    plan = DetectionPlan(free_minutes=args.minutes, false_positives_per_hour=args.budget)
    results = run_detection_evaluation(args.out, models, config, plan, n_jobs=args.jobs,
                                       progress=not args.quiet, in_loop=args.in_loop)
    print(markdown(results, plan))
    print(f"wrote {args.out}/detection.json, detection.md, detection_rate.png")
    return 0


def _meshcat():
    from pydrake.geometry import Meshcat

    return Meshcat()


if __name__ == "__main__":
    sys.exit(main())
