"""Where a process's CPU goes, by the library its samples fall in: `live_rate.py --perf DIR`
samples serve with Linux ``perf`` over the timed part of a run.

``perf record -F 99 -p PID`` samples the process's threads (all of them: the main thread,
the transport's receive threads) on the CPU clock at 99 Hz of their CPU time, without call
stacks; ``perf report --sort dso`` then gives each library's share of the samples. A run
of 30 s at 1 kHz gives about 500 samples: a share of 50 % is known to about ±2 % (one
binomial standard deviation). The shares are grouped
by what would have to change to remove them:

* ``python``: the interpreter (libpython), the Python code's own work: what compiling the
  per-message path would take away;
* ``numpy``: numpy's C code (small-array operations called from Python);
* ``numba``: the compiled kernels (perf's ``[JIT]`` code) and numba's dispatch into them;
* ``transport``: the transport's library (Cyclone DDS and its Python binding; LCM);
* ``kernel``: the operating system (wake-ups, context switches, the sockets);
* ``libc``: the C library (memory allocation, mostly the interpreter's; locks; clocks);
* ``other``: everything else (the struct and ctypes modules, libm, ...).

Each group is a percentage of the samples; times a run's CPU µs per message it is the
group's µs per message. The sampling rate is low because each sample costs serve CPU: on
this project's 2-core VM, sampling at 999 Hz made serve's CPU per message about 30 % higher;
at 99 Hz no difference was seen (docs/results/live.md).
"""

from __future__ import annotations

import re
import shutil
import signal
import subprocess
from pathlib import Path

RATE_HZ = 99  # samples per s of the process's CPU time (see above)
GROUPS = ("python", "numpy", "numba", "transport", "kernel", "libc", "other")

# The first pattern a library's name matches names its group.
_PATTERNS = (
    ("python", re.compile(r"^(libpython|python3)")),
    ("numpy", re.compile(r"^_multiarray_umath|^_umath|^lapack_lite|^_pocketfft")),
    ("numba", re.compile(r"^\[JIT\]|^_dispatcher\.|^_nrt_python\.|^_helperlib\.")),
    ("transport", re.compile(r"^libddsc|^_clayer\.|^liblcm|^_lcm\.|^lcm")),
    ("kernel", re.compile(r"^\[kernel")),
    ("libc", re.compile(r"^(libc\.so|libpthread|ld-linux|\[vdso\])")),
)


def require_perf() -> str:
    """The perf executable's path; a RuntimeError naming what is missing."""
    path = shutil.which("perf")
    if path is None:
        raise RuntimeError("--perf needs Linux perf on the PATH (Debian: apt install "
                           "linux-perf); it is not installed here")
    return path


def start(pid: int, data: Path) -> subprocess.Popen:
    """perf sampling process `pid` into `data` until :func:`stop`."""
    return subprocess.Popen([require_perf(), "record", "-q", "-F", str(RATE_HZ), "-p", str(pid),
                             "-o", str(data)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)


def stop(recorder: subprocess.Popen) -> None:
    """Ends the sampling (perf writes its file on SIGINT); a RuntimeError with perf's words
    if it failed (e.g. perf_event_paranoid forbids it)."""
    recorder.send_signal(signal.SIGINT)
    _, err = recorder.communicate(timeout=60)
    if recorder.returncode not in (0, -signal.SIGINT):
        raise RuntimeError(f"perf record failed ({recorder.returncode}): {err.strip()}")


def shares(data: Path) -> dict:
    """{"samples": n, "groups": {group: % of samples}, "libraries": {library: %}} of a perf
    file (the libraries with 0.5 % or more, largest first)."""
    report = subprocess.run([require_perf(), "report", "-i", str(data), "--sort", "dso",
                             "--stdio", "-q", "-n"], capture_output=True, text=True,
                            check=True)
    return grouped(report.stdout)


def grouped(report: str) -> dict:
    """The groups' and libraries' shares (%) of the samples, from the lines of ``perf report
    --sort dso -q -n`` (``  52.29%   732  libpython3.11.so.1.0``)."""
    counts = {}
    for line in report.splitlines():
        match = re.match(r"\s*[\d.]+%\s+(\d+)\s+(.+?)\s*$", line)
        if match:
            name = re.sub(r"^\[JIT\] tid \d+", "[JIT]", match.group(2))
            counts[name] = counts.get(name, 0) + int(match.group(1))
    total = sum(counts.values())
    if total == 0:
        raise RuntimeError("perf recorded no sample of serve (did the run's timed part "
                           "last long enough?)")
    groups = dict.fromkeys(GROUPS, 0.0)
    for name, count in counts.items():
        groups[group_of(name)] += 100.0 * count / total
    libraries = {name: 100.0 * count / total
                 for name, count in sorted(counts.items(), key=lambda item: -item[1])}
    return {"samples": total, "groups": groups,
            "libraries": {name: share for name, share in libraries.items() if share >= 0.5}}


def group_of(library: str) -> str:
    """The group (GROUPS) of a library as perf names it."""
    return next((group for group, pattern in _PATTERNS if pattern.search(library)), "other")
