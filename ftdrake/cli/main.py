"""The `ftdrake` command: simulate | collect | study | train | evaluate | demo."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..config import ConfigError, ScenarioConfig, load_config


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="ftdrake", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    _add_simulate(sub)
    _add_collect(sub)
    _add_demo(sub)
    _add_export(sub)
    from ..experiments import study
    from . import train

    study.register(sub)
    train.register(sub)
    args = parser.parse_args(argv)
    try:
        return args.run(args) or 0
    except (ConfigError, ValueError, FileNotFoundError) as e:
        print(f"ftdrake {args.command}: error: {e}", file=sys.stderr)
        return 2


def scenario_from_args(args, kind: str | None = None) -> ScenarioConfig:
    """Loads --config and applies --duration/--seed overrides common to commands."""
    config = load_config(args.config)
    if kind is not None:
        config.trajectory.kind = kind
    if getattr(args, "duration", None) is not None:
        config.trajectory.duration_s = args.duration
    if getattr(args, "seed", None) is not None:
        config.trajectory.seed = args.seed
        config.sensor.seed = args.seed
    return config.validate()


# ----------------------------------------------------------------------------------------------
def _add_simulate(sub):
    p = sub.add_parser("simulate", help="run the diagram once; write log, figure and summary")
    p.add_argument("--config", type=Path, help="scenario YAML (default: the shipped one)")
    p.add_argument("--scenario", choices=["free", "contact"], default="contact")
    p.add_argument("--duration", type=float, help="seconds to simulate")
    p.add_argument("--seed", type=int, help="seed of trajectory and sensor noise")
    p.add_argument("--out", type=Path, default=Path("out/simulate"))
    p.add_argument("--meshcat-html", action="store_true", help="also write replay.html")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=_simulate)


def _simulate(args):
    from ..io import atomic_path, staged_outputs
    from ..plots import plot_wrench_log
    from ..sim.simulate import simulate
    from ..sim.station import build_station

    config = scenario_from_args(args, "fourier" if args.scenario == "free" else "contact")
    meshcat = _meshcat() if args.meshcat_html else None
    station = build_station(config, meshcat=meshcat)
    if meshcat is not None:
        meshcat.StartRecording(set_visualizations_while_recording=False)
    result = simulate(station, progress=not args.quiet)
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
    p.add_argument("--trajectories", type=int, default=8)
    p.add_argument("--duration", type=float, default=20.0, help="seconds per trajectory")
    p.add_argument("--kind", choices=["random", "fourier", "reference", "z_rich", "rehearsal"],
                   default="fourier",
                   help="rehearsal: the contact scenario stopping 3 cm above the surface")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=-1, help="local worker processes (-1: all cores)")
    p.add_argument("--dask", metavar="ADDRESS", help="run on this Dask scheduler instead")
    p.add_argument("--out", type=Path, default=Path("out/dataset.parquet"))
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=_collect)


def _collect(args):
    from ..data.dataset import save_dataset
    from ..sim.collection import collect

    config = load_config(args.config)
    frame = collect(config, args.trajectories, seed=args.seed, kind=args.kind,
                    duration=args.duration, n_jobs=args.jobs, dask_address=args.dask,
                    progress=not args.quiet)
    save_dataset(frame, args.out)
    print(json.dumps({"out": str(args.out), "rows": len(frame),
                      "trajectories": int(frame["trajectory"].nunique()),
                      "contact_rows": int(frame["contact"].sum())}))
    return 0


def _add_demo(sub):
    p = sub.add_parser("demo", help="collect → train → contact scenario in the loop (main job)")
    p.add_argument("--config", type=Path, help="scenario YAML (default: the shipped one)")
    p.add_argument("--out", type=Path, default=Path("out/demo"))
    p.add_argument("--trajectories", type=int, default=4, help="Fourier runs to train on")
    p.add_argument("--duration", type=float, default=20.0, help="seconds per training run")
    p.add_argument("--no-html", action="store_true", help="skip the Meshcat replay")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=_demo)


def _demo(args):
    from ..experiments.demo import print_table, run_demo

    summary = run_demo(args.out, load_config(args.config), fourier=args.trajectories,
                       duration=args.duration, meshcat_html=not args.no_html,
                       progress=not args.quiet)
    print_table(summary)
    print(f"wrote {args.out}/summary.json, contact.png, model.ftd"
          + ("" if args.no_html else ", replay.html"))
    return 0


def _add_export(sub):
    p = sub.add_parser("export", help="a saved compensator → ONNX (for controllers outside Python)")
    p.add_argument("--model", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True, help="FILE.onnx")
    p.set_defaults(run=_export)


def _export(args):
    from ..compensation.onnx_export import export_onnx
    from ..compensation.persistence import load_model

    model = load_model(args.model)
    path = export_onnx(model, args.out)
    print(json.dumps({"out": str(path), "input": f"X float64 (N x {3 * model.n_joints_}) "
                      "= [q, qd, qdd]", "output": f"float64 (N x {model.n_outputs_})"}))
    return 0


def _meshcat():
    from pydrake.geometry import Meshcat

    return Meshcat()


if __name__ == "__main__":
    sys.exit(main())
