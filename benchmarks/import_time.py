"""Start-up cost of the command line and of the live station: CPU seconds and modules loaded.

Each command runs in a fresh interpreter (``python3 -m ftdrake ...``), several times; its CPU
time (user + system, of the child process: ``resource.getrusage(RUSAGE_CHILDREN)`` before and
after) is reported as the median and the range over the repeats. Then, each in one fresh
interpreter, the number of ftdrake modules (and of all modules) loaded by:

* ``import ftdrake.hardware.station`` (the live robot's station on LCM) and
  ``import ftdrake.hardware.ros2.station``, and which of them are of ``sim``, ``systems`` or
  ``experiments``;
* the ``serve`` command's path: ``ftdrake serve --model FILE`` run up to its first check, the
  model file (given a file that is not a model: the command stops there with its error), so
  that everything the command imports to get that far is counted;
* ``ftdrake --version``, with the heavy libraries (pydrake, scikit-learn, pandas, numba,
  scipy) it loads.

``--repo DIR`` measures another checkout (its ``ftdrake`` package is the one imported: the run's
working folder and ``PYTHONPATH`` are DIR), e.g. the main branch's, for a before/after.

    python benchmarks/import_time.py [--repo DIR] [--repeats 5]

Prints a table and, as its last line, one JSON object of every figure.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

COMMANDS = {
    "--version": ["--version"],
    "--help": ["--help"],
    "serve --help": ["serve", "--help"],
    "replay --help": ["replay", "--help"],
    "train --help": ["train", "--help"],
    "simulate --help": ["simulate", "--help"],
}
HEAVY = ("pydrake", "sklearn", "pandas", "numba", "scipy", "matplotlib", "dask", "skops",
         "onnxruntime", "pyarrow")

# Run in the child: import or run what is asked, then print what sys.modules holds.
_COUNT = """
import importlib, json, sys
what, arg, heavy = sys.argv[1], sys.argv[2], sys.argv[3].split(",")
status = None
if what == "import":
    importlib.import_module(arg)
else:
    from ftdrake.cli.main import main
    try:
        status = main(json.loads(arg))
    except SystemExit as e:
        status = e.code
import ftdrake
mods = [m for m in sys.modules if m.split(".")[0] == "ftdrake"]
print(json.dumps({
    "ftdrake_modules": len(mods), "all_modules": len(sys.modules), "status": status,
    "simulation": sorted(m for m in mods if m.split(".")[1:2] and m.split(".")[1] in
                         ("sim", "systems", "experiments")),
    "heavy": sorted({m.split(".")[0] for m in sys.modules} & set(heavy)),
    "package": ftdrake.__file__,
}))
"""


def environment(repo: Path) -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(repo), *filter(None, [os.environ.get("PYTHONPATH")])])}


def cpu_seconds(argv: list[str], repo: Path) -> float:
    """User + system CPU seconds of one child process running `argv` in `repo`."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(argv, cwd=repo, env=environment(repo), capture_output=True,
                          text=True, check=False, timeout=600)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({done.returncode}):\n{done.stderr}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def loaded(what: str, arg: str, repo: Path) -> dict:
    done = subprocess.run([sys.executable, "-c", _COUNT, what, arg, ",".join(HEAVY)], cwd=repo,
                          env=environment(repo), capture_output=True, text=True, check=False,
                          timeout=600)
    if done.returncode != 0:
        raise SystemExit(f"counting modules of {what} {arg} failed:\n{done.stderr}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repo", type=Path, default=ROOT,
                        help="the checkout whose ftdrake is measured (default: this one)")
    parser.add_argument("--repeats", type=int, default=5, help="runs per command")
    args = parser.parse_args()
    repo = args.repo.resolve()

    cpu = {}
    for name, command in COMMANDS.items():
        times = [cpu_seconds([sys.executable, "-m", "ftdrake", *command], repo)
                 for _ in range(args.repeats)]
        cpu[name] = {"median_s": round(statistics.median(times), 3),
                     "min_s": round(min(times), 3), "max_s": round(max(times), 3)}

    with tempfile.TemporaryDirectory() as folder:
        not_a_model = Path(folder) / "not_a_model.ftd"
        not_a_model.write_bytes(b"not a model file")
        counts = {
            "import ftdrake.hardware.station": loaded("import", "ftdrake.hardware.station",
                                                      repo),
            "import ftdrake.hardware.ros2.station": loaded(
                "import", "ftdrake.hardware.ros2.station", repo),
            "serve (up to its model check)": loaded(
                "run", json.dumps(["serve", "--model", str(not_a_model), "--duration", "1"]),
                repo),
            "--version": loaded("run", json.dumps(["--version"]), repo),
        }

    print(f"ftdrake at {counts['--version']['package']}; Python {platform.python_version()}, "
          f"{os.cpu_count()} cores, {args.repeats} runs per command")
    print("\n| command | CPU s (median) | min | max |\n| --- | --- | --- | --- |")
    for name, c in cpu.items():
        print(f"| `ftdrake {name}` | {c['median_s']:.3f} | {c['min_s']:.3f} "
              f"| {c['max_s']:.3f} |")
    print("\n| what | ftdrake modules | all modules | sim/systems/experiments | heavy |"
          "\n| --- | --- | --- | --- | --- |")
    for name, c in counts.items():
        print(f"| {name} | {c['ftdrake_modules']} | {c['all_modules']} | {len(c['simulation'])} "
              f"| {', '.join(c['heavy']) or '-'} |")
    print(json.dumps({"repo": str(repo), "repeats": args.repeats, "cpu_s": cpu,
                      "modules": {name: {"ftdrake": c["ftdrake_modules"],
                                         "all": c["all_modules"],
                                         "simulation": len(c["simulation"]),
                                         "heavy": c["heavy"]}
                                  for name, c in counts.items()}}))


if __name__ == "__main__":
    main()
