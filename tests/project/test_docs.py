"""The documentation site builds in strict mode from this checkout, and the HTML holds what the
generated parts promise: a page for every source page and every package, each Drake system's
ports drawn from the code, every command's usage, no unrendered reference, no broken link."""

import html
import importlib
import inspect
import os
import pkgutil
import re
import subprocess
import sys
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest
from pydrake.systems.framework import PortDataType, System

import ftdrake
from tests.helpers import ROOT

DOCS = ROOT / "docs"


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": str(ROOT)}
    result = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(out)],
                            cwd=ROOT, env=env, capture_output=True, text=True, timeout=900,
                            check=False)
    assert result.returncode == 0, result.stderr[-5000:]
    (out.parent / "build.log").write_text(result.stdout + result.stderr)  # beside the site
    return out


def page(site: Path, src: str) -> Path:
    """The built HTML of a source page (use_directory_urls off: a/b.md -> a/b.html)."""
    return site / (src.removesuffix(".md") + ".html")


def source_pages() -> list[str]:
    return [p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")
            if not p.relative_to(DOCS).parts[0] in ("hooks", "_moved")]


def packages() -> list[str]:
    return [".".join(init.parent.relative_to(ROOT).parts)
            for init in (ROOT / "ftdrake").rglob("__init__.py")
            if not any(part.startswith("_") for part in init.parent.relative_to(ROOT).parts)]


def system_classes() -> list[type]:
    found = []
    for info in pkgutil.walk_packages(ftdrake.__path__, "ftdrake."):
        if info.name.rsplit(".", 1)[-1].startswith("_"):
            continue
        module = importlib.import_module(info.name)
        found += [cls for _, cls in inspect.getmembers(module, inspect.isclass)
                  if cls.__module__ == info.name and issubclass(cls, System)]
    return found


def test_every_source_page_and_every_package_has_a_page(site):
    missing = [src for src in source_pages() if not page(site, src).is_file()]
    assert not missing
    for package in packages():
        text = (site / "api" / f"{package}.html").read_text(encoding="utf-8")
        assert f'id="{package}"' in text  # the package's docstring rendered under its name
    assert len(packages()) >= 10


def test_no_reference_is_left_unrendered(site):
    for path in site.rglob("*.html"):
        text = path.read_text(encoding="utf-8")
        for bad in ("::: ftdrake", "Could not collect", "ftdrake-usage:", "ftdrake-diagram:",
                    "ftdrake-code-layout", "ftdrake-moved-notes", "ftdrake-examples -->",
                    ":class:`", ":func:`", ":meth:`", ":mod:`"):
            assert bad not in text, f"{path.relative_to(site)}: '{bad}'"
        # mkdocstrings' name appears only in its stylesheet's link, never as a message
        assert not re.search(r"mkdocstrings(?!\.css)", text), path.relative_to(site)


def test_every_drake_system_is_drawn_with_the_ports_of_a_live_instance(site):
    classes = system_classes()
    assert {"CompensationChain", "CompensatorSystem", "OnlineBiasTracker", "ContactDetector",
            "NoisyForceTorqueSensor"} <= {c.__name__ for c in classes}
    for cls in classes:
        svg = site / "diagrams" / f"{cls.__name__}.svg"
        assert svg.is_file(), cls.__name__
        api = (site / "api" / f"{cls.__module__.rsplit('.', 1)[0]}.html").read_text(
            encoding="utf-8")
        assert f"Ports of <code>{cls.__name__}</code>" in api  # inline, under its heading


def test_the_chain_api_page_shows_every_port_with_its_size(site):
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (50, 22))  # 7 joints and the temperature: every optional input
    model = ftdrake.RandomForestCompensator(features="q", n_estimators=2).fit(
        X, rng.normal(size=(50, 6)))
    config = ftdrake.ScenarioConfig()
    config.chain.bias_tracker.track_payload = config.chain.bias_tracker.track_payload_motion = True
    dut = ftdrake.CompensationChain(model, config.chain_config(), gravity="input")
    ports = [dut.get_input_port(i) for i in range(dut.num_input_ports())] + [
        dut.get_output_port(i) for i in range(dut.num_output_ports())]
    api = (site / "api" / "ftdrake.runtime.html").read_text(encoding="utf-8")
    figure = re.search(r'<figure class="ftdrake-ports">(.*?)</figure>',
                       api[api.index('id="ftdrake.runtime.chain.CompensationChain"'):], re.DOTALL)
    labels = set(re.findall(r"<text[^>]*>([^<]*)</text>", figure.group(1)))
    for port in ports:
        assert port.get_data_type() == PortDataType.kVectorValued
        assert f"{port.get_name()} ({port.size()})" in {html.unescape(t) for t in labels}
    assert len(ports) == 18


def test_every_command_usage_comes_from_the_parser(site):
    reference = (site / "guide" / "commands" / "index.html").read_text(encoding="utf-8")
    commands = re.findall(r"^    (\S+)\s", subprocess.run(
        [sys.executable, "-m", "ftdrake", "--help"], capture_output=True, text=True,
        check=True, env={**os.environ, "COLUMNS": "100", "PYTHONPATH": str(ROOT)}
    ).stdout.split("commands:")[1], re.MULTILINE)
    commands = [c for c in commands if not c.startswith("{")]
    assert "train" in commands and "serve" in commands
    for command in commands:
        assert html.escape(f"usage: ftdrake {command} ") in reference, command


def test_every_internal_link_and_image_resolves(site):
    broken = []
    for path in site.rglob("*.html"):
        text = path.read_text(encoding="utf-8")
        for url in re.findall(r'(?:href|src)="([^"]+)"', text):
            parts = urlsplit(html.unescape(url))
            if parts.scheme or parts.netloc or url.startswith(("#", "mailto:", "data:")):
                continue
            base = site if parts.path.startswith("/") else path.parent  # 404.html: from the root
            target = (base / unquote(parts.path).lstrip("/")).resolve()
            if not target.is_file():  # a folder too: only servers that list folders show it
                broken.append(f"{path.relative_to(site)} -> {url}")
                continue
            if parts.fragment and target.suffix == ".html":
                anchor = f'id="{parts.fragment}"'
                if anchor not in target.read_text(encoding="utf-8"):
                    broken.append(f"{path.relative_to(site)} -> {url} (no anchor)")
    assert not broken, "\n".join(broken[:20])


# -- what a reader sees (issue 42, item 22) ------------------------------------------------------
def test_the_build_prints_no_meshcat_address(site):
    log = (site.parent / "build.log").read_text()
    assert "listening" not in log.lower() and "localhost:" not in log


def test_usage_blocks_fit_the_text_column(site):
    reference = (site / "guide" / "commands" / "index.html").read_text(encoding="utf-8")
    blocks = re.findall(r"<pre[^>]*>(.*?)</pre>", reference, re.DOTALL)
    usage = [html.unescape(re.sub(r"<[^>]+>", "", b)) for b in blocks if "usage: ftdrake" in b]
    assert len(usage) >= 13
    wide = [line for block in usage for line in block.splitlines() if len(line) > 78]
    assert not wide, wide[:5]


def test_the_station_drawing_is_shown_at_its_size_with_a_link(site):
    text = (site / "guide" / "diagram.html").read_text(encoding="utf-8")
    figure = re.search(r'<figure class="ftdrake-wide">(.*?)</figure>', text, re.DOTALL).group(1)
    assert 'href="../diagrams/station.svg"' in figure and "open the drawing alone" in figure
    width = re.search(r'width="(\d+)"', (site / "diagrams" / "station.svg").read_text()).group(1)
    assert f"max-width: none; width: {width}px" in figure


def test_the_runtime_page_opens_with_the_chain(site):
    text = (site / "api" / "ftdrake.runtime.html").read_text(encoding="utf-8")
    modules = re.findall(r'<h2 id="(ftdrake\.runtime\.\w+)"', text)
    assert modules[0] == "ftdrake.runtime.chain", modules
    assert modules.index("ftdrake.runtime.chain") < modules.index(
        "ftdrake.runtime.bias_estimator")
