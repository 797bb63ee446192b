"""MkDocs hook: every Drake system of ftdrake drawn with its ports, from live instances.

At each build the hook builds the simulated station (with a tiny fitted model, every event,
friction and payload tracking on, so every optional port exists), the runtime chain for a
live robot, and the systems the station does not hold; it then draws one SVG per system
class: a box with its input ports on the left and its output ports on the right, each with
its size (``abstract`` for a non-vector port), read from the instance's port list. The
pictures cannot go stale; a system class that no instance here covers is a warning (which
fails the strict build) naming the class to add to ``_extra_instances``.

Where they appear:

* ``diagrams/<Class>.svg`` (generated files) and, inline, under the class's heading on its
  API page;
* ``<!-- ftdrake-diagram: NAME -->`` in a page becomes the picture (``NAME`` a class name;
  ``station``: the simulated station's block diagram, its subsystems connected as built;
  ``chain``: the runtime chain's insides as the live robot's station builds it).
"""

from __future__ import annotations

import html
import importlib
import inspect
import logging
import pkgutil
import posixpath
import re
import sys
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[2]
MARKER = re.compile(r"<!-- ftdrake-diagram: ([\w]+) -->")
LOG = logging.getLogger("mkdocs.plugins.ftdrake.port_diagrams")
CHAR_W, ROW_H, PAD = 7.0, 20, 12
FONT = "font-family:Menlo,Consolas,monospace;font-size:12px"
COLUMN_PX = 760  # the text column's width in the site's theme (px), about
HIDDEN_IN_STATION = ("VectorLogSink",)  # the station's loggers: one per signal, not the data path


# -- live instances ----------------------------------------------------------------------------

def _tiny_model(n_joints: int = 7, temperature: bool = True):
    """A 2-tree forest on random rows, with the temperature column so the compensator's
    optional temperature input exists."""
    import numpy as np  # noqa: PLC0415 (the hook imports the project only when it runs)

    from ftdrake import RandomForestCompensator  # noqa: PLC0415

    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (60, 3 * n_joints + int(temperature)))
    return RandomForestCompensator(features="q", n_estimators=2, n_jobs=1,
                                   random_state=0).fit(X, rng.normal(size=(60, 6)))


def _full_scenario():
    from ftdrake import ScenarioConfig  # noqa: PLC0415

    config = ScenarioConfig()
    config.events.retare_at_s, config.events.grasp_at_s, config.events.push_at_s = 1.0, 1.5, 2.0
    config.friction.enabled = True
    config.encoders.enabled = True
    config.chain.bias_tracker.track_payload = True
    config.chain.bias_tracker.track_payload_motion = True
    return config


def build_station():
    """The simulated station with every optional part, and its tiny model."""
    import numpy as np  # noqa: PLC0415
    from pydrake.trajectories import PiecewisePolynomial  # noqa: PLC0415

    import ftdrake  # noqa: PLC0415

    config, model = _full_scenario(), _tiny_model()
    hold = PiecewisePolynomial(np.asarray(config.home_q, dtype=float).reshape(-1, 1))
    return ftdrake.build_station(config, model, trajectory=hold), model


def _extra_instances(station, model) -> list:
    """Systems the simulated station does not hold."""
    import numpy as np  # noqa: PLC0415

    import ftdrake  # noqa: PLC0415
    from ftdrake.config import ImuConfig, PayloadChangeConfig, TransmissionConfig  # noqa: PLC0415
    from ftdrake.runtime.delay_line import DelayLine  # noqa: PLC0415
    from ftdrake.runtime.payload_change import PayloadChangeMonitor  # noqa: PLC0415
    from ftdrake.sim.scene import CONTROL_SENSOR_FRAME, make_control_plant  # noqa: PLC0415
    from ftdrake.systems.imu import ImuNoise  # noqa: PLC0415
    from ftdrake.systems.learned_feedforward import LearnedFeedforward  # noqa: PLC0415
    from ftdrake.systems.payload_feedforward import PayloadFeedforward  # noqa: PLC0415
    from ftdrake.systems.time_indexed_feedforward import TimeIndexedFeedforward  # noqa: PLC0415
    from ftdrake.systems.transmission import MotorSide  # noqa: PLC0415
    from ftdrake.systems.wrench_arrows import WrenchArrows, recording_meshcat  # noqa: PLC0415

    config = station.config
    n = station.plant.num_positions(station.scene.arm)
    live = live_chain(station, model)
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (40, 3 * n))
    torque = ftdrake.GPRCompensator(features="q,qd,qdd", max_points=20).fit(
        X, rng.normal(size=(40, n)))
    control_plant = make_control_plant(config, station.scene)
    meshcat = recording_meshcat()  # for WrenchArrows; no "listening" line in the build's log
    return [live, *live.GetSystems(), LearnedFeedforward(torque, n_joints=n),
            TimeIndexedFeedforward(np.zeros((10, n)), config.time_step),
            WrenchArrows(meshcat, station.plant, station.scene),
            DelayLine(6, 2.5, config.time_step),
            MotorSide(TransmissionConfig(enabled=True), config.time_step),
            ImuNoise(ImuConfig(), config.time_step),
            PayloadChangeMonitor(PayloadChangeConfig(enabled=True), config.sensor),
            PayloadFeedforward(control_plant, control_plant.GetFrameByName(CONTROL_SENSOR_FRAME))]


def _is_ftdrake(system) -> bool:
    return type(system).__module__.startswith("ftdrake.")


def _walk(system):
    yield system
    if hasattr(system, "GetSystems"):
        for child in system.GetSystems():
            yield from _walk(child)


def live_chain(station, model):
    """The runtime chain as a live robot's station builds it (gravity from the joint state)."""
    import ftdrake  # noqa: PLC0415

    config = station.config.chain_config()
    config.robot.file = "ftdrake"  # the forest carries no robot: the simulated arm's kinematics
    return ftdrake.CompensationChain(model, config, gravity="joint_state")


def instances(station, model) -> dict:
    """{class: an instance}, the instance with the most ports when several exist."""
    found: dict = {}
    for system in [*_walk(station.diagram), *_extra_instances(station, model)]:
        for sub in _walk(system):
            if not _is_ftdrake(sub):
                continue
            cls = type(sub)
            ports = sub.num_input_ports() + sub.num_output_ports()
            if cls not in found or ports > (found[cls].num_input_ports()
                                            + found[cls].num_output_ports()):
                found[cls] = sub
    return found


def system_classes() -> list:
    """Every Drake System subclass defined in an ftdrake module."""
    from pydrake.systems.framework import System  # noqa: PLC0415

    import ftdrake  # noqa: PLC0415

    classes = []
    for info in pkgutil.walk_packages(ftdrake.__path__, "ftdrake."):
        if info.name.rsplit(".", 1)[-1].startswith("_"):
            continue
        module = importlib.import_module(info.name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ == info.name and issubclass(cls, System):
                classes.append(cls)
    return classes


# -- drawing ------------------------------------------------------------------------------------

def _port_label(port) -> str:
    from pydrake.systems.framework import PortDataType  # noqa: PLC0415

    size = (str(port.size()) if port.get_data_type() == PortDataType.kVectorValued
            else "abstract")
    return f"{port.get_name()} ({size})"


def ports(system) -> tuple[list[str], list[str]]:
    return ([_port_label(system.get_input_port(i)) for i in range(system.num_input_ports())],
            [_port_label(system.get_output_port(i)) for i in range(system.num_output_ports())])


def _text(x, y, s, anchor="start", weight="normal") -> str:
    return (f'<text x="{x:.1f}" y="{y:.1f}" text-anchor="{anchor}" font-weight="{weight}" '
            f'style="{FONT}">{html.escape(s)}</text>')


def system_svg(system, title: str) -> str:
    """A box titled `title`, inputs left, outputs right, each an arrow and a label."""
    inputs, outputs = ports(system)
    left = max((len(s) for s in inputs), default=0) * CHAR_W
    right = max((len(s) for s in outputs), default=0) * CHAR_W
    box_w = max(left + right + 3 * PAD, len(title) * CHAR_W + 2 * PAD, 120)
    rows = max(len(inputs), len(outputs), 1)
    box_h = 34 + rows * ROW_H
    arrow = 28
    width, height = box_w + 2 * arrow + 4, box_h + 8
    x0, y0 = arrow + 2, 4
    parts = [(f'<svg xmlns="http://www.w3.org/2000/svg" class="ftdrake-ports" '
              f'width="{width:.0f}" height="{height:.0f}" '
              f'viewBox="0 0 {width:.0f} {height:.0f}" '
              f'role="img" aria-label="{html.escape(title)} ports">'),
             f"<title>{html.escape(title)}: input and output ports</title>",
             ('<defs><marker id="arrow" markerWidth="8" markerHeight="8" refX="7" refY="4" '
              'orient="auto"><path d="M0,0 L8,4 L0,8 z" fill="#444"/></marker></defs>'),
             (f'<rect x="{x0}" y="{y0}" width="{box_w:.1f}" height="{box_h}" rx="6" '
              'fill="#eef2fb" stroke="#3f51b5" stroke-width="1.5"/>'),
             _text(x0 + box_w / 2, y0 + 20, title, "middle", "bold")]
    for side, labels in (("in", inputs), ("out", outputs)):
        for k, label in enumerate(labels):
            y = y0 + 34 + k * ROW_H + ROW_H / 2
            if side == "in":
                parts.append(f'<line x1="2" y1="{y}" x2="{x0}" y2="{y}" stroke="#444" '
                             'marker-end="url(#arrow)"/>')
                parts.append(_text(x0 + PAD, y + 4, label))
            else:
                xe = x0 + box_w
                parts.append(f'<line x1="{xe:.1f}" y1="{y}" x2="{xe + arrow - 2:.1f}" y2="{y}" '
                             'stroke="#444" marker-end="url(#arrow)"/>')
                parts.append(_text(xe - PAD, y + 4, label, "end"))
    parts.append("</svg>")
    return "\n".join(parts)


def station_svg(diagram) -> str:
    """The diagram's subsystems in columns by data flow (feedback edges drawn below), each
    box with the ports that are connected, each connection an arrow between ports."""
    systems = [s for s in diagram.GetSystems() if type(s).__name__ not in HIDDEN_IN_STATION]
    keep = set(map(id, systems))
    edges = [(src, int(o), dst, int(i)) for (dst, i), (src, o) in diagram.connection_map().items()
             if id(src) in keep and id(dst) in keep]
    layer = _layers(systems, edges)
    used_in = {id(s): sorted({i for _, _, d, i in edges if d is s}) for s in systems}
    used_out = {id(s): sorted({o for s_, o, _, _ in edges if s_ is s}) for s in systems}
    boxes = {}
    columns: dict[int, list] = {}
    for s in systems:
        columns.setdefault(layer[id(s)], []).append(s)
    x = 10.0
    for col in sorted(columns):
        col_w = 0.0
        y = 10.0
        for s in columns[col]:
            ins = [s.get_input_port(i).get_name() for i in used_in[id(s)]]
            outs = [s.get_output_port(o).get_name() for o in used_out[id(s)]]
            title = s.get_name()
            w = max(max((len(a) for a in ins), default=0) * CHAR_W
                    + max((len(a) for a in outs), default=0) * CHAR_W + 3 * PAD,
                    len(title) * CHAR_W + 2 * PAD)
            h = 30 + max(len(ins), len(outs), 1) * ROW_H
            boxes[id(s)] = (x, y, w, h, title, used_in[id(s)], used_out[id(s)], ins, outs)
            y += h + 24
            col_w = max(col_w, w)
        x += col_w + 90
    bottom = max(b[1] + b[3] for b in boxes.values()) + 20
    parts = []
    back = 0
    for src, o, dst, i in edges:
        sx, sy = _port_xy(boxes[id(src)], "out", o)
        dx, dy = _port_xy(boxes[id(dst)], "in", i)
        if layer[id(dst)] > layer[id(src)]:
            mid = (sx + dx) / 2
            d = f"M{sx:.1f},{sy:.1f} C{mid:.1f},{sy:.1f} {mid:.1f},{dy:.1f} {dx:.1f},{dy:.1f}"
        else:  # feedback: out to the right, along the bottom, in from the left
            back += 1
            lane = bottom + 8 * back
            d = (f"M{sx:.1f},{sy:.1f} H{sx + 10 + 4 * back:.1f} V{lane:.1f} "
                 f"H{dx - 10 - 4 * back:.1f} V{dy:.1f} H{dx:.1f}")
        parts.append(f'<path d="{d}" fill="none" stroke="#666" stroke-width="1.2" '
                     'marker-end="url(#arrow)"/>')
    for x0, y0, w, h, title, _, _, ins, outs in boxes.values():
        parts.append(f'<rect x="{x0:.1f}" y="{y0:.1f}" width="{w:.1f}" height="{h}" rx="5" '
                     'fill="#eef2fb" stroke="#3f51b5" stroke-width="1.3"/>')
        parts.append(_text(x0 + w / 2, y0 + 18, title, "middle", "bold"))
        for k, name in enumerate(ins):
            parts.append(_text(x0 + 6, y0 + 30 + k * ROW_H + 14, name))
        for k, name in enumerate(outs):
            parts.append(_text(x0 + w - 6, y0 + 30 + k * ROW_H + 14, name, "end"))
    width = max(b[0] + b[2] for b in boxes.values()) + 30
    height = bottom + 8 * back + 14
    head = (f'<svg xmlns="http://www.w3.org/2000/svg" class="ftdrake-station" '
            f'width="{width:.0f}" height="{height:.0f}" viewBox="0 0 {width:.0f} {height:.0f}" '
            'role="img" aria-label="the simulated station">'
            "<title>The simulated station: its subsystems and connections</title>"
            '<defs><marker id="arrow" markerWidth="8" markerHeight="8" refX="7" refY="4" '
            'orient="auto"><path d="M0,0 L8,4 L0,8 z" fill="#666"/></marker></defs>')
    return "\n".join([head, *parts, "</svg>"])


def _port_xy(box, side, index):
    x0, y0, w, _, _, used_in, used_out, _, _ = box
    k = (used_in if side == "in" else used_out).index(index)
    return (x0 if side == "in" else x0 + w), y0 + 30 + k * ROW_H + 10


def _layers(systems, edges) -> dict:
    """Column of each system: the longest path to it from a source once the edges that close
    a cycle (found by a depth-first search in build order) are left out."""
    succ = {id(s): [] for s in systems}
    for src, _, dst, _ in edges:
        succ[id(src)].append(id(dst))
    state, order, back = {}, [], set()

    def visit(u):
        state[u] = 1
        for v in succ[u]:
            if state.get(v) == 1:
                back.add((u, v))
            elif v not in state:
                visit(v)
        state[u] = 2
        order.append(u)

    sources = [id(s) for s in systems if not any(d is s for _, _, d, _ in edges)]
    for u in sources + [id(s) for s in systems]:
        if u not in state:
            visit(u)
    layer = dict.fromkeys(succ, 0)
    for u in reversed(order):
        for v in succ[u]:
            if (u, v) not in back:
                layer[v] = max(layer[v], layer[u] + 1)
    for u in sources:  # a source sits just before its first consumer
        if succ[u]:
            layer[u] = max(0, min(layer[v] for v in succ[u]) - 1)
    return layer


# -- mkdocs events -------------------------------------------------------------------------------

_svgs: dict[str, str] = {}
_paths: dict[str, str] = {}  # class name -> dotted path of the class


def on_pre_build(config):  # noqa: ARG001
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    _svgs.clear()
    station, model = build_station()
    found = instances(station, model)
    for cls, system in found.items():
        _svgs[cls.__name__] = system_svg(system, cls.__name__)
        _paths[cls.__name__] = f"{cls.__module__}.{cls.__qualname__}"
    _svgs["station"] = station_svg(station.diagram)
    _svgs["chain"] = station_svg(live_chain(station, model))
    for cls in system_classes():
        if cls not in found:
            LOG.warning(f"{cls.__module__}.{cls.__name__}: a Drake system with no instance to "
                        "draw; add one in docs/hooks/port_diagrams.py (_extra_instances)")


def on_files(files, config):
    for name, svg in _svgs.items():
        files.append(File.generated(config, f"diagrams/{name}.svg", content=svg))
    return files


def on_page_markdown(markdown, page, config, files):  # noqa: ARG001
    def replace(match):
        name = match.group(1)
        if name not in _svgs:
            LOG.warning(f"{page.file.src_uri}: <!-- ftdrake-diagram: {name} --> names no drawn "
                        f"system (drawn: {', '.join(sorted(_svgs))})")
            return ""
        link = posixpath.relpath(f"diagrams/{name}.svg", posixpath.dirname(page.file.src_uri))
        caption = {"station": "the simulated station, drawn from build_station",
                   "chain": "inside CompensationChain (as a live robot's station builds it)",
                   }.get(name, f"{name}: its ports, drawn from a live instance")
        return wide_figure(_svgs[name], link, caption) or f"![{caption}]({link})"

    return MARKER.sub(replace, markdown)


def wide_figure(svg: str, link: str, caption: str) -> str | None:
    """A drawing wider than the text column (:data:`COLUMN_PX`) at its own size, scrolled
    sideways inside the column, with a link to the drawing alone; None for a narrower one
    (an image in the text, as it is)."""
    width = float(re.search(r'width="([\d.]+)"', svg).group(1))
    if width <= COLUMN_PX:
        return None
    alt, href = html.escape(caption), html.escape(link)
    return (f'<figure class="ftdrake-wide">'
            f'<div style="overflow-x: auto"><a href="{href}"><img src="{href}" alt="{alt}" '
            f'style="max-width: none; width: {width:.0f}px"></a></div>'
            f'<figcaption>{alt} ({width:.0f} px wide: scroll sideways, or '
            f'<a href="{href}">open the drawing alone</a>)</figcaption></figure>')


def on_page_content(html_text, page, config, files):  # noqa: ARG001
    """Under each system class's heading on an API page, its port diagram (inline SVG)."""
    if not page.file.src_uri.startswith("api/"):
        return html_text
    for name, path in _paths.items():
        heading = re.compile(rf'(<h(\d)[^>]*\bid="{re.escape(path)}"[^>]*>.*?</h\2>)', re.DOTALL)
        figure = (f'<figure class="ftdrake-ports">{_svgs[name]}<figcaption>Ports of '
                  f"<code>{name}</code>, drawn from a live instance</figcaption></figure>")
        html_text = heading.sub(lambda m, f=figure: m.group(1) + f, html_text, count=1)
    return html_text
