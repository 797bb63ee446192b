"""``--ros2`` for ``ftdrake serve``, ``simulate`` and ``record``: the same commands on ROS 2
topics (Cyclone DDS, no ROS installation needed).

    ftdrake serve --ros2 --ros2-config ros2.yaml --model m.ftd [--config chain.yaml]
    ftdrake simulate --ros2 --ros2-config ros2.yaml --realtime [--trajectory fourier]
    ftdrake record --ros2 --ros2-config ros2.yaml --out log.parquet [--duration S]

``--ros2-config`` is a :class:`~ftdrake.hardware.ros2.config.Ros2Config` YAML (topics, QoS,
the model's joint names in its order, timeouts, ``domain_id``, ``dds_config``);
``--ros2-domain`` overrides its ``domain_id``. serve prints the topics, a status line twice a
second, each fault and recovery (stderr), and on Ctrl-C or after ``--duration`` a JSON summary
(stdout), as on LCM.

:func:`add_options` adds the flags to a parser; the commands call :func:`serve`,
:func:`record` and :func:`simulate` when ``args.ros2`` is set.
"""

from __future__ import annotations

import json
import sys
import time

from ..config import load_config
from ..errors import ConfigError
from . import args as a
from .live import (
    describe_cpus,
    describe_path,
    load_live,
    serve_until_stopped,
    starting,
    stop_on_signals,
)


def add_options(p) -> None:
    """Adds ``--ros2``, ``--ros2-config FILE`` and ``--ros2-domain N`` to parser `p`."""
    p.add_argument("--ros2", action="store_true", help="use ROS 2 topics (Cyclone DDS) instead "
                   "of LCM; see --ros2-config")
    p.add_argument("--ros2-config", type=a.existing_file, metavar="FILE",
                   help="Ros2Config YAML: topics, QoS, joint_names in the model's order, "
                        "timeouts, domain_id, dds_config")
    p.add_argument("--ros2-domain", type=a.non_negative_int, metavar="N",
                   help="ROS_DOMAIN_ID (default: the --ros2-config file's domain_id, else 0)")


def config_from_args(args, live=None):
    """The Ros2Config of --ros2-config (else the live config's ``ros2:`` section, else the
    defaults) with --ros2-domain applied."""
    from ..hardware.ros2.config import Ros2Config

    path = args.ros2_config
    if path is None:
        config = live.ros2 if live is not None else Ros2Config()
    else:
        with a.naming("--ros2-config", path):
            config = load_config(path, schema=Ros2Config)
    if args.ros2_domain is not None:
        config.domain_id = args.ros2_domain
    if path is None:
        try:
            return config.validate()
        except ConfigError as e:
            raise ConfigError(f"--ros2 needs --ros2-config FILE (a Ros2Config YAML; the "
                              f"defaults used without it fall short): {e}") from None
    with a.naming("--ros2-config", path):
        return config.validate()


def describe_topics(config) -> str:
    c = config
    outs = ", ".join(c.output_topic(name) for name in ("wrench_contact", "wrench_compensated",
                                                         "contact", "contact_force"))
    return (f"ROS 2 domain {c.domain_id} (DDS: {c.dds_config})\n"
            f"  in:  {c.joint_state_topic} (JointState, {c.joint_state_qos}); "
            f"{c.wrench_topic} (WrenchStamped, {c.wrench_qos})\n"
            f"  out: {outs}; {c.diagnostics_topic} (DiagnosticArray)" + describe_cpus(c))


def serve(args) -> int:
    """``ftdrake serve --ros2``."""
    from ..compensation.files.persistence import load_model
    from ..hardware.ros2.station import Ros2Station

    live = load_live(args)
    config = config_from_args(args, live)

    def on_event(event) -> None:
        print(f"ftdrake serve: {event}", file=sys.stderr, flush=True)

    def on_warning(warning: str) -> None:
        print(f"ftdrake serve: warning: {warning}", file=sys.stderr, flush=True)

    with starting(args.model, args.quiet):
        with a.naming("--model", args.model):
            model = load_model(args.model)  # its joints against ros2.joint_names: the station's
        station = Ros2Station(config, model, live.chain, on_event=on_event,
                              on_warning=on_warning)
    print(f"ftdrake serve: {type(model).__name__} from {args.model}, "
          f"{1 / station.period:g} Hz updates, per-message path: "
          f"{describe_path(station.compiled)}\n"
          f"{describe_topics(config)}", file=sys.stderr, flush=True)
    summary = serve_until_stopped(station, args.duration, args.quiet,
                                  before_summary=lambda: station.node.wait_for_acks(1.0))
    summary["diagnostics_published"] = station.diagnostics_published
    station.close()
    print(json.dumps(summary))
    return 0


def record(args) -> int:
    """``ftdrake record --ros2``."""
    if getattr(args, "data", None) is not None:
        raise ConfigError("--data reads an LCM log; a ROS 2 bag needs no conversion: "
                          "train and evaluate read it directly")
    from ..hardware.recording import write_table
    from ..hardware.ros2.recording import Ros2Recorder

    config = config_from_args(args)
    recorder = Ros2Recorder(config)
    print(f"ftdrake record: {describe_topics(config).splitlines()[1].strip()} → {args.out}",
          file=sys.stderr, flush=True)
    start = time.monotonic()
    with stop_on_signals() as stop:
        while not stop[0]:
            recorder.spin(10)
            if args.duration is not None and time.monotonic() - start >= args.duration:
                break
    recorder.spin(0)
    recorder.close()
    table, report = recorder.table(args.tolerance)
    write_table(table, args.out)
    print(json.dumps({"out": str(args.out), **report}))
    return 0


def simulate(args, station):
    """``ftdrake simulate --ros2``: the simulated robot on ROS 2; returns the SimResult."""
    from ..sim.ros2_publisher import arm_joint_names, simulate_on_ros2

    config = config_from_args_for_simulation(args, station, arm_joint_names)
    print(f"ftdrake simulate: publishing {describe_topics(config).splitlines()[1]}"
          .replace("  in:  ", ""), file=sys.stderr, flush=True)
    return simulate_on_ros2(station, config, realtime_rate=1.0 if args.realtime else 0.0,
                            progress=not args.quiet, wait_for_subscriber_s=2.0)


def config_from_args_for_simulation(args, station, arm_joint_names):
    """As config_from_args; without joint_names in the file, the simulated arm's."""
    from ..hardware.ros2.config import Ros2Config

    if args.ros2_config is None:
        config = Ros2Config(joint_names=arm_joint_names(station))
        if args.ros2_domain is not None:
            config.domain_id = args.ros2_domain
        return config.validate()
    return config_from_args(args)
