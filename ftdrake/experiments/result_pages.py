"""The results pages' files and the commands that write them: one table, one regenerator.

Every figure on a page under ``docs/results/`` is rendered at the docs build from a result file
under ``docs/`` (``docs/hooks/result_files.py``), and every result file records the command and
the commit that wrote it (:func:`ftdrake.version.result_provenance`). :data:`RESULTS` says, for
each result, the page that cites it, the commands that write it and the files they write that
are copied into ``docs/``. :func:`regenerate` runs them (``ftdrake results --regenerate``):
each command writes into its own folder under a work folder, and only when every command of a
result has succeeded are its files copied over the ones in ``docs/``.

``quick`` runs each command at a tiny size (its ``quick`` arguments) into the work folder and
copies nothing: it checks that the commands still run and write the files the pages cite.
"""

from __future__ import annotations

import dataclasses as dc
import json
import os
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

from ..errors import ConfigError, FtdrakeError
from ..io import atomic_path

#: The checkout's docs folder (the result files live there).
DOCS = Path(__file__).resolve().parents[2] / "docs"


@dc.dataclass(frozen=True)
class Step:
    """One command of a result. ``argv`` follows ``ftdrake`` (or is ``python SCRIPT ...``);
    ``{out}`` is the step's own folder, ``{work}`` the work folder (another step's output is
    ``{work}/<step name>``). ``quick`` replaces ``argv``'s tail at the quick size. ``env``:
    extra environment variables."""

    name: str
    argv: tuple
    quick: tuple = ()
    env: tuple = ()

    def command(self, work: Path, *, quick: bool = False) -> list:
        argv = [a.format(out=work / self.name, work=work) for a in self.argv]
        if quick:
            argv += list(self.quick)
        return argv if argv[0] == "python" else ["ftdrake", *argv]

    def shown(self, work: Path, *, quick: bool = False) -> str:
        env = " ".join(f"{k}={v}" for k, v in self.env)
        return (env + " " if env else "") + shlex.join(self.command(work, quick=quick))


@dc.dataclass(frozen=True)
class Result:
    """A result: the `page` that cites it, its `steps` (run in order) and `files`, each
    ``(step name, file it writes, path under docs/)``. `minutes`: how long a full run took on
    the 2-core VM as its page reports it, for the list when its files record no
    ``wall_time_s`` (None: not recorded)."""

    name: str
    page: str
    steps: tuple
    files: tuple
    minutes: float | None

    def wall_time_s(self) -> float | None:
        """The wall time recorded by this result's first JSON file, if it records one."""
        for _, _, target in self.files:
            path = DOCS / target
            if path.suffix == ".json" and path.is_file():
                seconds = json.loads(path.read_text(encoding="utf-8")).get("wall_time_s")
                if isinstance(seconds, (int, float)):
                    return float(seconds)
        return None

    def provenance(self) -> dict:
        """The provenance record of this result's first JSON file under docs/ ({} if none)."""
        for _, _, target in self.files:
            path = DOCS / target
            if path.suffix == ".json" and path.is_file():
                return json.loads(path.read_text(encoding="utf-8")).get("provenance") or {}
        return {}


_DEMO = Step("demo", ("demo", "--no-html", "--out", "{out}"),
             quick=("--trajectories", "1", "--duration", "12"))
_MODELS = ("--model", "{work}/demo/model_forest.ftd", "--model", "{work}/demo/model_hybrid.ftd")

#: Every result a page cites, in the order of the Results section.
#: The contour runs' GP fits on one BLAS thread (their figures are reproducible so).
_ONE_THREAD = (("OMP_NUM_THREADS", "1"),)

RESULTS = (
    Result("demo", "results/demo.md", (_DEMO,),
           (("demo", "summary.json", "demo/summary.json"),
            ("demo", "contact.png", "demo/contact.png")), 6),
    Result("detection", "results/detection.md",
           (_DEMO, Step("detection", ("evaluate-detection", *_MODELS, "--out", "{out}"),
                        quick=("--quick", "--minutes", "0.2"))),
           (("detection", "detection.json", "detection/detection.json"),
            ("detection", "detection.md", "detection/detection.md"),
            ("detection", "detection_rate.png", "detection/detection_rate.png")), None),
    Result("detection-compare-tests", "results/detection.md",
           (_DEMO, Step("compare_tests", ("evaluate-detection", *_MODELS, "--compare-tests",
                                          "--out", "{out}"),
                        quick=("--quick", "--minutes", "0.2"))),
           (("compare_tests", "detection.json", "detection/compare_tests/detection.json"),
            ("compare_tests", "detection.md", "detection/compare_tests/detection.md")), 3.3),
    Result("detection-all-surfaces", "results/detection.md",
           (Step("demo_all", ("demo", "--no-html", "--rehearse-all-surfaces", "--out",
                              "{out}"), quick=("--trajectories", "1", "--duration", "12")),
            Step("all_surfaces", ("evaluate-detection", "--model",
                                  "{work}/demo_all/model_forest.ftd", "--model",
                                  "{work}/demo_all/model_hybrid.ftd", "--out", "{out}"),
                 quick=("--quick", "--minutes", "0.2"))),
           (("demo_all", "summary.json", "detection/all_surfaces/demo_summary.json"),
            ("all_surfaces", "detection.json", "detection/all_surfaces/detection.json"),
            ("all_surfaces", "detection.md", "detection/all_surfaces/detection.md"),
            ("all_surfaces", "detection_rate.png", "detection/all_surfaces/detection_rate.png")),
           None),
    Result("study", "results/study.md",
           (Step("study", ("study", "--quick", "--out", "{out}"),
                 quick=("--trajectories", "2", "--test-trajectories", "1", "--duration",
                        "4")),),
           (("study", "results.json", "study/results.json"),
            ("study", "results.md", "study/results.md")), None),
    Result("study-paper", "results/study.md",
           (Step("paper", ("study", "--paper", "--features", "q", "--max-train-rows", "1000",
                           "--jobs", "2", "--out", "{out}"),
                 quick=("--trajectories", "2", "--test-trajectories", "1", "--duration", "4",
                        "--max-train-rows", "100")),),
           (("paper", "paper.json", "study/paper.json"), ("paper", "paper.md", "study/paper.md")),
           None),
    Result("feedforward", "results/feedforward.md",
           (Step("feedforward", ("learn-feedforward", "--out", "{out}"),
                 quick=("--iterations", "1", "--duration", "12")),),
           (("feedforward", "summary.json", "feedforward/summary.json"),
            ("feedforward", "iterations.csv", "feedforward/iterations.csv"),
            ("feedforward", "tracking.png", "feedforward/tracking.png")), None),
    Result("feedforward-feedback-target", "results/feedforward.md",
           (Step("feedback_target", ("learn-feedforward", "--target", "feedback", "--out",
                                     "{out}"), quick=("--iterations", "1", "--duration", "12")),),
           (("feedback_target", "summary.json", "feedforward/summary_feedback_target.json"),),
           None),
    Result("two-part", "results/two-part.md",
           (Step("two_part", ("learn-feedforward", "--two-part", "--out", "{out}"),
                 quick=("--iterations", "1"), env=_ONE_THREAD),),
           (("two_part", "summary.json", "two_part/summary.json"),
            ("two_part", "iterations.csv", "two_part/iterations.csv"),
            ("two_part", "contours.npz", "two_part/contours.npz"),
            ("two_part", "contour.png", "two_part/contour.png")), None),
    Result("two-part-family", "results/two-part.md",
           (Step("family_quick", ("learn-feedforward", "--two-part", "--family", "quick",
                                  "--out", "{out}"), quick=("--iterations", "1"), env=_ONE_THREAD),
            Step("family_more", ("learn-feedforward", "--two-part", "--family", "quick",
                                 "--members", "tilted_x20,3d_reoriented,slot_corners",
                                 "--out", "{out}"), quick=("--iterations", "1"), env=_ONE_THREAD),
            Step("family_rest", ("learn-feedforward", "--two-part", "--family", "quick",
                                 "--members", "hole_10_elsewhere,hole_60_elsewhere,tilted_y20",
                                 "--out", "{out}"), quick=("--iterations", "1"), env=_ONE_THREAD)),
           tuple((run, name, f"feedforward/{run}/{name}")
                 for run in ("family_quick", "family_more", "family_rest")
                 for name in ("summary.json", "transfer.json", "learning_curve.json")),
           None),
)


def find(names) -> list:
    """The results named in `names` (all when empty); an unknown name is a ConfigError that
    lists the names."""
    if not names:
        return list(RESULTS)
    known = {r.name: r for r in RESULTS}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ConfigError(f"no result named {', '.join(map(repr, unknown))}; the results are: "
                          + ", ".join(known))
    return [known[n] for n in names]


def listing(results, work: Path) -> str:
    """A table: each result, its page, its commands, when its files were made and how long a
    full run takes."""
    lines = []
    for r in results:
        prov = r.provenance()
        seconds = r.wall_time_s()
        took = (f"{seconds / 60:.1f} min (its file's wall_time_s)" if seconds
                else f"about {r.minutes:g} min (its page)" if r.minutes
                else "time not recorded")
        lines.append(f"{r.name}  →  docs/{r.page}; {took}; files at "
                     f"{prov.get('commit', 'no commit recorded')}"
                     f" ({prov.get('written', '?')})")
        lines += [f"    {s.shown(work)}" for s in r.steps]
    lines.append("A step shared by several results (the demo's models) runs once per call.")
    return "\n".join(lines)


def regenerate(results, work: Path, *, quick: bool = False, dry_run: bool = False,
               quiet: bool = False) -> list:
    """Runs each result's steps into `work` (a step already run for an earlier result of the
    same call is not run again) and, unless `quick`, copies its files into docs/. Returns the
    docs/ paths written. A failed step raises :class:`~ftdrake.errors.FtdrakeError` naming
    the result and the command, and leaves docs/ as it was for that result. `quiet`: no
    progress lines, and each command gets ``--quiet``."""
    say = (lambda *_: None) if quiet else print
    if not (quick or dry_run) and not DOCS.is_dir():
        raise FtdrakeError(f"no docs/ folder at {DOCS}: regenerating the results pages' files "
                           "needs a checkout of ftdrake (git clone), not an installed wheel")
    done: set = set()
    written = []
    for r in results:
        started = time.perf_counter()
        for step in r.steps:
            if step.name not in done:
                say(f"[{r.name}] {step.shown(work, quick=quick)}")
                if not dry_run:
                    _run(r.name, step.command(work, quick=quick), dict(step.env),
                         quiet=quiet)
                done.add(step.name)
        if dry_run:
            continue
        missing = [f"{work / s / f}" for s, f, _ in r.files if not (work / s / f).is_file()]
        if missing:
            raise ConfigError(f"result {r.name}: its commands did not write "
                              + ", ".join(missing))
        if not quick:
            for step_name, name, target in r.files:
                with atomic_path(DOCS / target) as tmp:
                    shutil.copyfile(work / step_name / name, tmp)
                written.append(f"docs/{target}")
        say(f"[{r.name}] done in {time.perf_counter() - started:.0f} s")
    return written


def _run(result: str, argv: list, env: dict, *, quiet: bool) -> None:
    """Runs one step's command with this interpreter (``ftdrake`` as ``python -m ftdrake``)."""
    shown = shlex.join(argv)
    if argv[0] == "ftdrake":
        argv = [sys.executable, "-m", "ftdrake", *argv[1:], *(["--quiet"] if quiet else [])]
    elif argv[0] == "python":
        argv = [sys.executable, *argv[1:]]
    done = subprocess.run(argv, check=False, env={**os.environ, **env})
    if done.returncode != 0:
        raise FtdrakeError(f"result {result}: `{shown}` failed (exit {done.returncode}, its "
                           "message above); docs/ is unchanged for this result")
