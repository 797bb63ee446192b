"""``python -m ftdrake.hardware.fast.warm MODULE ARGUMENTS.pkl``: compiles a compiled
path's loop for the pickled arguments' types into numba's on-disk cache (or finds it
there), by ``MODULE.warm(arguments)``: one dry call. :class:`~.path.CompiledPathBase` runs
it in a process of its own, so that the station's Python path serves meanwhile (a first
compile takes tens of seconds and holds the interpreter), and then loads the loop from that
cache. Exit 1 with the reason on stderr when the transport's C functions cannot be had."""

from __future__ import annotations

import importlib
import pickle
import sys


def main(argv: list[str]) -> int:
    module = importlib.import_module(argv[0])
    with open(argv[1], "rb") as f:
        arguments = pickle.load(f)  # written by this process's parent
    problem = module.warm(arguments)
    if problem is not None:
        print(problem, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
