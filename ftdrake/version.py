"""The installed ftdrake's version (the lowest layer: anything may import it)."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version


def ftdrake_version() -> str:
    """The installed distribution's version, or ``"0.0.0+unknown"`` in an uninstalled tree."""
    try:
        return version("ftdrake")
    except PackageNotFoundError:
        return "0.0.0+unknown"


def source_commit() -> str:
    """``git describe --always --dirty`` of the tree ftdrake is imported from (a ``-dirty``
    suffix: uncommitted changes), or ``"ftdrake <version>"`` when that tree is not a git
    checkout (an installed wheel) or git is missing."""
    import subprocess  # noqa: PLC0415 (only a result writer pays for it)
    from pathlib import Path  # noqa: PLC0415

    root = Path(__file__).resolve().parents[1]
    try:
        done = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=root,
                              capture_output=True, text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        done = None
    if done is None or done.returncode != 0 or not done.stdout.strip():
        return f"ftdrake {ftdrake_version()}"
    return done.stdout.strip()


def run_command(argv=None) -> str:
    """The command line that is running, as a user would type it: ``ftdrake CMD ...`` for the
    command-line tool (its entry point or ``python -m ftdrake``), else ``python SCRIPT ...``."""
    import shlex  # noqa: PLC0415
    import sys  # noqa: PLC0415
    from pathlib import Path  # noqa: PLC0415

    argv = list(sys.argv if argv is None else argv)
    program = Path(argv[0]) if argv else Path("python")
    if program.name == "ftdrake" or (program.name == "__main__.py"
                                     and program.parent.name == "ftdrake"):
        return shlex.join(["ftdrake", *argv[1:]])
    return shlex.join(["python", *argv])


def result_provenance(command: str | None = None) -> dict:
    """What a result file records about how it was made: ``command`` (default: the running
    command line, :func:`run_command`), ``commit`` (:func:`source_commit`) and ``written``
    (the UTC date). Result pages render it beside the figures (docs/hooks/result_files.py)."""
    import datetime  # noqa: PLC0415

    return {"command": command or run_command(), "commit": source_commit(),
            "written": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d")}
