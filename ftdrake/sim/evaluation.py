"""Contact detection and compensation in the loop, evaluated against the plant's ground truth.

A log from :func:`ftdrake.sim.simulate.simulate` of a station built with a compensator holds
both the truth (``contact``, ``internal_*``, ``external_*``) and what the compensator and
detector made of the noisy stream (``pred_*``, ``est_external_*``, ``detected``);
:func:`evaluate_detection` compares them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import conventions as col

STARTUP_SAMPLES = 2  # the sensor chain reads the plant's pre-step zero for this many samples
TOUCHDOWN_S = 0.02  # s after each contact onset left out of the "after touchdown" error

def evaluate_detection(log: pd.DataFrame, noise_std) -> dict:
    """Detection and compensation quality against the plant's ground truth.

    * detection_delay_s: per true contact episode, first detection minus true onset (a
      detection within 0.5 s before the onset counts as early, delay < 0).
    * false_positives: detection onsets that do not overlap any true contact (± 0.5 s).
    * missed_contacts: true contact episodes with no detection during them.
    * external_wrench_error_rms: RMS of estimated − true external wrench while in contact;
      ..._after_touchdown: the same without the first TOUCHDOWN_S of each contact, where a
      millisecond-long impact spike, seen one sample late, dominates the RMS.
    * compensation_error_rms: RMS of predicted − true internal wrench in free motion, and
      that over the sensor noise σ (compensation_error_over_noise). The first
      STARTUP_SAMPLES rows are excluded (reported as excluded_startup_samples): before the
      plant's first step its sampled outputs read zero, and the compensator, one sample behind
      the sensor, sees that zero as a measurement.
    """
    t = log[col.TIME].to_numpy()
    truth = log[col.CONTACT].to_numpy().astype(bool)
    detected = log[col.DETECTED].to_numpy().astype(bool)
    true_eps, det_eps = _episodes(truth), _episodes(detected)
    margin = 0.5
    delays, missed = [], 0
    for a, b in true_eps:
        hits = [s for s, e in det_eps if t[s] <= t[b - 1] and t[e - 1] >= t[a] - margin]
        if hits:
            delays.append(float(t[min(hits)] - t[a]))
        else:
            missed += 1
    false_pos = sum(
        1 for s, e in det_eps
        if not any(t[s] <= t[b - 1] + margin and t[e - 1] >= t[a] - margin for a, b in true_eps)
    )
    free = ~truth
    free[:STARTUP_SAMPLES] = False
    pred = log[col.wrench_columns(col.PREDICTED)].to_numpy()
    internal = log[col.wrench_columns(col.INTERNAL)].to_numpy()
    comp_rms = np.sqrt(np.mean((pred[free] - internal[free]) ** 2, axis=0))
    est = log[col.wrench_columns(col.ESTIMATED)].to_numpy()
    ext = log[col.wrench_columns(col.EXTERNAL)].to_numpy()
    ext_rms = (np.sqrt(np.mean((est[truth] - ext[truth]) ** 2, axis=0))
               if truth.any() else np.full(6, np.nan))
    steady = truth.copy()
    for a, _ in true_eps:  # the touchdown transient: a spike the compensator sees 1 sample late
        steady[(t >= t[a]) & (t < t[a] + TOUCHDOWN_S)] = False
    steady_rms = (np.sqrt(np.mean((est[steady] - ext[steady]) ** 2, axis=0))
                  if steady.any() else np.full(6, np.nan))
    return {
        "true_contacts": len(true_eps),
        "detected_contacts": len(det_eps),
        "detection_delay_s": delays[0] if len(delays) == 1 else (delays or None),
        "false_positives": int(false_pos),
        "missed_contacts": int(missed),
        "external_wrench_error_rms": ext_rms.tolist(),
        "external_wrench_error_rms_after_touchdown": steady_rms.tolist(),
        "compensation_error_rms": comp_rms.tolist(),
        "compensation_error_over_noise": (comp_rms / np.asarray(noise_std)).tolist(),
        "out_of_domain_fraction": float(log[col.OUT_OF_DOMAIN].mean()),
        "fault_samples": int(log[col.FAULT].sum()),
        "excluded_startup_samples": STARTUP_SAMPLES,
    }


def _episodes(flags: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of runs of True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2], strict=True))
