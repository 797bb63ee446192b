"""The IMU stream of a live station, for a model that takes an IMU at the sensor.

Each accepted IMU sample ``(t s, [f_S (m/s²); ω_S (rad/s)])`` is kept in a short history;
the F/T sample stamped t is paired with the IMU sample stamped nearest to t, within
``max_skew_s``, as the joint state is paired by stamp. When none is that close (the IMU is
late, silent or its stamps drift), the pair is NaN: the chain's compensator then faults
for that sample (its outputs hold their last good values), so a stale IMU reading is never
passed on as a fresh one; ``problem`` then names why (``imu_missing``: no IMU sample yet;
``imu_stamp_gap``: none stamped close enough) with the fix, and the station faults its
inputs with it (the StreamMonitor's reason, the status, ``/diagnostics``, the fault
episodes). A malformed, non-finite or out-of-order IMU message is rejected and counted;
one stamped :data:`~.live_inputs.CLOCK_RESTART_S` or more before the last is the IMU's
clock restarting (a looped bag, a restarted driver): the history starts again from it.
"""

from __future__ import annotations

import collections

import numpy as np

from .live_inputs import CLOCK_RESTART_S

#: Values per IMU sample: the accelerometer's f_S (3, m/s²), then the gyroscope's ω_S (3,
#: rad/s), both in S (the chain's ``imu`` input).
IMU_VALUES = 6


class ImuPairing:
    """IMU samples by stamp, paired with F/T stamps (module docstring).

    `max_skew_s`: the largest |t_imu − t_ft| (s) of a pair. `history`: samples kept.
    `source` and `skew_key` name, in the details, the configured IMU input and the skew's
    config key (e.g. ``"hardware.imu_channel 'FT_IMU'"``, ``"hardware.imu_max_skew_s"``).
    Counters: ``accepted``, ``rejected`` (reason → count), ``unpaired`` (F/T samples that
    found no IMU sample close enough). ``problem``: (reason, detail) of the last pairing
    that failed, None after one that succeeded.
    """

    def __init__(self, max_skew_s: float, history: int = 64, *,
                 source: str = "the IMU input", skew_key: str = "imu_max_skew_s"):
        if not (max_skew_s > 0 and np.isfinite(max_skew_s)):
            raise ValueError(f"max_skew_s must be a positive number of seconds; got "
                             f"{max_skew_s!r}")
        self.max_skew_s = float(max_skew_s)
        self._samples: collections.deque = collections.deque(maxlen=int(history))
        self._missing = np.full(IMU_VALUES, np.nan)
        self.accepted = 0
        self.unpaired = 0
        self.restarts = 0  # times the IMU's stamps went back CLOCK_RESTART_S or more
        self.rejected: collections.Counter = collections.Counter()
        self.source, self.skew_key = source, skew_key
        self.problem: tuple[str, str] | None = None  # why the last pairing failed

    @property
    def detail(self) -> str:
        """Why the last pairing failed, in words ("" after one that succeeded)."""
        return self.problem[1] if self.problem is not None else ""

    def counts(self) -> dict:
        """``accepted``, ``rejected`` (reason → count), ``unpaired`` and ``clock_restarts``
        so far."""
        return {"accepted": self.accepted, "rejected": dict(self.rejected),
                "unpaired": self.unpaired, "clock_restarts": self.restarts}

    def on_imu(self, sample) -> bool:
        """One IMU message ``(t, values (6,))`` (None when it failed to decode)."""
        if sample is None:
            self.rejected["malformed"] += 1
            return False
        t, values = sample
        values = np.asarray(values, dtype=float)
        if values.shape != (IMU_VALUES,):
            self.rejected["malformed"] += 1
            return False
        if not (np.isfinite(t) and np.isfinite(values).all()):
            self.rejected["not_finite"] += 1
            return False
        if self._samples and t <= self._samples[-1][0]:
            if self._samples[-1][0] - t < CLOCK_RESTART_S:
                self.rejected["out_of_order"] += 1
                return False
            self._samples.clear()  # the IMU's clock restarted (live_inputs.CLOCK_RESTART_S)
            self.restarts += 1
        self._samples.append((float(t), values))
        self.accepted += 1
        return True

    def pair(self, t: float) -> np.ndarray:
        """The IMU values stamped nearest to `t` (s) within ``max_skew_s``; NaN (6) when
        there is none (``unpaired`` counts it, ``problem`` says why)."""
        if not self._samples:
            self.unpaired += 1
            rejected = ", ".join(f"{n} {r}" for r, n in sorted(self.rejected.items()))
            self.problem = ("imu_missing", (
                "no IMU sample received yet"
                + (f" ({rejected} rejected)" if rejected else "")
                + ": the model takes an IMU at the sensor, so the wrench is not compensated. "
                f"Fix: publish the IMU on {self.source}, or set it to the one that carries "
                "it"))
            return self._missing
        nearest_t, nearest = min(self._samples, key=lambda item: abs(item[0] - t))
        if abs(nearest_t - t) <= self.max_skew_s:
            self.problem = None
            return nearest
        self.unpaired += 1
        newest = self._samples[-1][0]
        why = (f"the newest IMU sample is {(t - newest) * 1e3:.1f} ms older: the IMU is late "
               "or silent" if newest < t - self.max_skew_s
               else "the IMU's stamps are off the F/T sensor's, or it samples too slowly")
        self.problem = ("imu_stamp_gap", (
            f"no IMU sample stamped within {self.max_skew_s * 1e3:g} ms of the F/T sample at "
            f"{t:.6f} s (nearest {(nearest_t - t) * 1e3:+.1f} ms; {why}): the wrench is not "
            f"compensated. Fix: the IMU's driver on {self.source}, its clock or stamps, or "
            f"{self.skew_key}"))
        return self._missing
