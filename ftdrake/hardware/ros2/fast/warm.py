"""``python -m ftdrake.hardware.ros2.fast.warm ARGUMENTS.pkl``: compiles the compiled
path's loop (:func:`.loop.run`) for the pickled arguments' types into numba's on-disk cache
(or finds it there), by one dry call. :class:`~.path.CompiledPath` runs it in a process of
its own, so that the station's Python path serves meanwhile (a first compile takes tens of
seconds and holds the interpreter), and then loads the loop from that cache."""

from __future__ import annotations

import pickle
import sys

from . import cyclone
from .loop import run


def main(argv: list[str]) -> int:
    with open(argv[0], "rb") as f:
        arguments = pickle.load(f)  # written by this process's parent
    c = cyclone.load()
    if isinstance(c, str):
        print(c, file=sys.stderr)
        return 1
    run(c, *arguments)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
