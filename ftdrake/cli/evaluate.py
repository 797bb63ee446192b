"""`ftdrake evaluate`: score a saved compensator on a robot log, per target.

It reads the log as `train` does (:mod:`ftdrake.cli.train`: the same read flags; those not
given are the ones the model was trained with), and reports per-target MSE, NMSE and variance
score on all rows, on the rows inside the training range of every input, and on the rows
outside it, with the trust flags of :mod:`ftdrake.compensation.evaluation.trust`.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..compensation.estimators.build import same_targets
from ..compensation.evaluation.evaluation import MIN_REST_RUN, REST_SPEED, evaluate_model
from ..compensation.files.persistence import load_model, read_manifest
from ..conventions import TEMPERATURE
from ..data.bag import is_bag
from ..data.training import ReadOptions, TrainingData
from ..errors import ConfigError, LogError, ModelFileError
from ..io import atomic_write_text
from . import args as a
from .train import (
    COLUMNS_HELP,
    FILE_OPTIONS,
    add_read_flags,
    read_data,
    reporter,
    warn,
    with_flags,
)


def register(subparsers) -> None:
    """Adds ``evaluate`` to an ``argparse`` subparsers object."""
    p = a.add_command(
        subparsers, "evaluate", "score a saved compensator on a robot log",
        description=COLUMNS_HELP + " Read flags not given are those the model was trained "
        "with (column and topic flags: when the file is of the same kind, table or bag), else "
        "the defaults.")
    a.add_model_file(p, required=True)
    p.add_argument("--data", type=a.existing_path, required=True, metavar="FILE",
                   help="CSV/Parquet table, ROS 1 .bag file or ROS 2 bag folder")
    add_read_flags(p)
    p.add_argument("--noise-std", type=a.noise_values, metavar="S[,S...]",
                   help="the sensor's noise std, one value or one per target (the targets' "
                        "units): errors are also given in σ units (≈1 at the noise floor); "
                        "without it, estimated from resting rows when the log has them")
    p.add_argument("--json", type=a.output_file, metavar="OUT",
                   help="also write the results as JSON")
    a.add_quiet(p)
    p.set_defaults(run=run_evaluate)


def stored_read_options(manifest: dict, path: Path) -> ReadOptions:
    """The ReadOptions a model was trained with, for reading `path`: all of them when `path`
    is of the same kind (table or bag) as the training data, else only those that are not
    about columns and topics."""
    trained_on = manifest.get("extra", {}).get("data", {})
    stored = dict(trained_on.get("options") or {})
    if trained_on.get("kind") != ("bag" if is_bag(path) else "table"):
        stored = {k: v for k, v in stored.items() if k not in FILE_OPTIONS}
    try:
        return ReadOptions.from_dict(stored)
    except ConfigError as e:
        raise ModelFileError(f"--model: the manifest's read options: {e}") from None


def run_evaluate(args) -> int:
    say = reporter(args.quiet)
    with a.naming("--model", args.model):
        manifest = read_manifest(args.model)
    options = with_flags(stored_read_options(manifest, args.data), args)
    # A table without its time column is a table of static poses (what `calibrate` takes).
    data = read_data(args, options, say, static_poses=None)
    _check_compatible(manifest, data, args)
    model = load_model(args.model, expect_n_joints=data.n_joints)
    _check_temperature(model, data, args)

    names = data.target_names
    ranges = manifest.get("extra", {}).get("training_range", {}).get("targets")
    noise = args.noise_std
    if noise is not None and len(noise) not in (1, len(names)):
        raise ConfigError(f"--noise-std gives {len(noise)} values for {len(names)} targets "
                          f"{names}: give one, or one per target")
    scores = evaluate_model(model, data.X, data.Y, target_names=names, training_ranges=ranges,
                            noise_std=noise)
    result = {
        "model": str(args.model),
        "model_class": manifest["model_class"].rsplit(".", 1)[-1],
        "data": str(args.data),
        "source": data.source,
        "rows": data.rows,
        "reader_warnings": data.warnings,
        **{key: scores[key] for key in ("in_domain_rows", "out_of_domain_rows",
                                        "out_of_domain_fraction", "out_of_domain_by_input")},
        "target_units": dict(zip(names, manifest["target_units"], strict=True)),
        **{key: scores[key] for key in ("std", "metrics", "min_subset_rows", "noise",
                                        "trust")},
    }
    result["offsets"] = scores["offsets"]
    print_evaluation(result)
    for line in scores["trust"]["warnings"]:
        warn(line)
    for line in offset_warnings(result):
        warn(line)
    if args.json is not None:
        atomic_write_text(args.json, json.dumps(result, indent=2))
        say(f"wrote {args.json}")
    return 0


def offset_warnings(result: dict) -> list[str]:
    """A warning per target whose residual's mean is many of its std from zero (a bias or a
    payload change, not the model's scatter), with the scores that hide or show it."""
    lines = []
    for name, o in result.get("offsets", {}).items():
        unit = result["target_units"].get(name, "")
        row = result["metrics"]["all"][name]
        lines.append(
            f"warning: {name}: the residual's mean {o['mean']:+.4g} {unit} is "
            f"{abs(o['mean']) / o['std'] if o['std'] > 0 else float('inf'):.1f} × its std "
            f"({o['std']:.4g} {unit}) from zero: a constant offset, not the model's scatter — "
            "a sensor bias or re-tare, or a payload changed since the training data; the "
            f"variance score ({_num(row['variance_score'], 0, '.3f')}) ignores a constant, the "
            f"nmse ({_num(row['nmse'], 0, '.3f')}) counts it. A new payload: identify it "
            "(ftdrake calibrate) or retrain; a bias: the bias tracker removes it (replay, "
            "serve)")
    return lines


def _check_compatible(manifest: dict, data: TrainingData, args) -> None:
    trained = manifest.get("extra", {}).get("columns", {})
    if manifest["n_joints"] != data.n_joints:
        raise LogError(
            f"{args.model} was trained on {manifest['n_joints']} joints "
            f"{trained.get('joints', '')}; {args.data.name} gives {data.n_joints} "
            f"{data.joint_names}: another robot, or pass --positions"
        )
    if manifest["n_outputs"] != len(data.target_names):
        raise LogError(
            f"{args.model} predicts {manifest['n_outputs']} targets {manifest['target_names']}; "
            f"{args.data.name} gives {len(data.target_names)} {data.target_names}: pass --targets"
        )
    if not same_targets(manifest["target_names"], data.target_names):
        warn(f"warning: target names differ: model {manifest['target_names']}, "
              f"data {data.target_names}; compared in this order")


def _check_temperature(model, data: TrainingData, args) -> None:
    """A model trained with the sensor temperature needs it in the data, and the other way
    round; the error names the column and the flag."""
    needs = bool(getattr(model, "temperature_in_", False))
    if needs and not data.has_temperature:
        raise LogError(
            f"{args.model} was trained with the sensor temperature (°C) as an input; "
            f"{args.data.name} was read without one: name its column with --temperature COL "
            f"(e.g. --temperature {TEMPERATURE})")
    if data.has_temperature and not needs:
        raise LogError(
            f"{args.model} was trained without the sensor temperature; omit --temperature "
            f"{data.options.temperature}")


def print_evaluation(result: dict, file=None) -> None:
    """The evaluation as a small table: all rows, then variance score in and out of domain."""
    file = file or sys.stdout
    m = result["metrics"]
    print(f"\n{result['model']} ({result['model_class']}) on {result['data']}: "
          f"{result['rows']['used']} rows, {result['out_of_domain_rows']} "
          f"({100 * result['out_of_domain_fraction']:.1f} %) outside the training range",
          file=file)
    worst = sorted(result["out_of_domain_by_input"].items(), key=lambda kv: -kv[1])[:4]
    if worst:
        print("  rows outside, by input: " + ", ".join(f"{k} {v}" for k, v in worst), file=file)
    sigma = result.get("noise") is not None
    print(f"\n  {'target':<10}{'unit':<6}{'mse':>11}{'nmse':>8}"
          + (f"{'rms/σ':>8}" if sigma else "")
          + f"{'var.score':>11}{'in-domain':>11}{'out-of-dom.':>12}", file=file)
    print(f"  {'rows':<16}{result['rows']['used']:>{30 + 8 * sigma}}"
          f"{result['in_domain_rows']:>11}{result['out_of_domain_rows']:>12}", file=file)
    for name, row in m["all"].items():
        parts = [m[k][name]["variance_score"] if m[k] else None
                 for k in ("in_domain", "out_of_domain")]
        print(f"  {name:<10}{result['target_units'][name]:<6}{_num(row['mse'], 11, '.4g')}"
              f"{_num(row['nmse'], 8, '.3f')}"
              + (_num(row.get("rms_over_sigma"), 8, ".2f") if sigma else "")
              + f"{_num(row['variance_score'], 11, '.3f')}"
              f"{_num(parts[0], 11, '.3f')}{_num(parts[1], 12, '.3f')}", file=file)
    print("  (in-domain / out-of-domain columns: variance score on those rows; not given on "
          f"fewer than {result.get('min_subset_rows', 2)} rows)", file=file)
    if sigma:
        noise = result["noise"]
        print("  rms/σ: RMS error in units of the sensor's noise std σ (≈1 at the noise "
              f"floor); σ {', '.join(f'{v:.3g}' for v in noise['std'])} from "
              f"{noise['source']}", file=file)
    else:
        print(f"  no rms/σ column: the log holds no stretch at rest to measure the sensor's "
              f"noise σ on (≥ {2 * MIN_REST_RUN} rows in runs of ≥ {MIN_REST_RUN} with every "
              f"|q̇| < {REST_SPEED:g} rad/s; a table of static poses has none); give σ with "
              "--noise-std S[,S...]", file=file)
    print(file=file)
    if result.get("std"):
        rows = m["in_domain"] or m["all"]
        which = "in-domain" if m["in_domain"] else "all"
        print(f"  coverage of the predictive std ({result['std']}), {which} rows: fraction "
              "within the central 68 % / 95 % interval", file=file)
        for name, row in rows.items():
            print(f"  {name:<10}{_num(row.get('coverage_68'), 8, '.3f')}"
                  f"{_num(row.get('coverage_95'), 8, '.3f')}", file=file)
        print(file=file)
    trust = result.get("trust")
    if trust:
        _print_trust(trust, file)


def _print_trust(trust: dict, file) -> None:
    """Per target: the share of rows flagged, and by which cause; then what "untrusted"
    means (the same for every model) and the branch of it that applied."""
    causes = trust.get("flagging_causes", list(trust["by_cause"]))
    short = {"inputs_outside_range": "inputs", "std_above_factor_x_residual": "std",
             "prediction_outside_target_range": "range"}
    counted = [c for c in trust["by_cause"] if c not in causes]  # counted, flagging nothing
    print(f"  rows flagged as not to be trusted, per target ({', '.join(short[c] for c in causes)}"
          "):", file=file)
    for name, share in trust["untrusted_fraction"].items():
        detail = ", ".join(f"{short[c]} {100 * trust['by_cause'][c][name]:.0f} %" for c in causes)
        detail += "".join(f"; {short[c]} {100 * trust['by_cause'][c][name]:.0f} % not flagging"
                          for c in counted)
        print(f"  {name:<10}{100 * share:5.0f} %  ({detail})", file=file)
    if "meaning" in trust:
        print(f"  ({trust['meaning']})", file=file)
    if "explanation" in trust:
        print(f"  ({trust['explanation']})", file=file)
    print(file=file)


def _num(x, width: int, fmt: str) -> str:
    return f"{'–':>{width}}" if x is None else f"{x:>{width}{fmt}}"
