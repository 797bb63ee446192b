"""Contact detection and compensation in the loop, evaluated against the plant's ground truth.

A log from :func:`ftdrake.sim.simulate.simulate` of a station built with a compensator holds
both the truth (``contact_true``, ``internal_true_*``, ``external_true_*``) and what the
compensator and detector made of the noisy stream (``wrench_internal_*``, ``wrench_contact_*``,
``contact``);
:func:`evaluate_detection` compares them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import conventions as col
from ..errors import LogError

STARTUP_SAMPLES = 2  # the sensor chain reads the plant's pre-step zero for this many samples
TOUCHDOWN_S = 0.02  # s after each contact onset left out of the "after touchdown" error

def evaluate_detection(log: pd.DataFrame, noise_std, replayed: pd.DataFrame | None = None
                       ) -> dict:
    """Detection and compensation quality against the plant's ground truth.

    `log` holds the truth and, from a station with a compensator (or ``add_recorder(chain=)``),
    the chain's outputs; `replayed` (optional) is :func:`ftdrake.replay`'s result on the same
    rows, whose columns then replace the log's chain outputs. Columns read (and what makes
    them): see ``INPUTS``. ``t``, ``contact_true``, ``contact``, ``out_of_domain`` and
    ``fault`` are required (a LogError names a missing one and its source); the wrench errors
    need ``wrench_contact_*`` with ``external_true_*``, the compensation error
    ``wrench_internal_*`` with ``internal_true_*`` — without them those entries are None and
    ``not_computed`` says why.

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
    log = _with_replay(log, replayed)
    _require(log, [col.TIME, col.CONTACT_TRUE, col.CONTACT, col.OUT_OF_DOMAIN, col.FAULT])
    not_computed = {}
    t = log[col.TIME].to_numpy()
    truth = log[col.CONTACT_TRUE].to_numpy().astype(bool)
    detected = log[col.CONTACT].to_numpy().astype(bool)
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
    comp_rms = ext_rms = steady_rms = None
    if _available(log, (col.WRENCH_INTERNAL, col.INTERNAL_TRUE), "compensation_error_rms",
                  not_computed):
        pred = log[col.wrench_columns(col.WRENCH_INTERNAL)].to_numpy()
        internal = log[col.wrench_columns(col.INTERNAL_TRUE)].to_numpy()
        comp_rms = np.sqrt(np.mean((pred[free] - internal[free]) ** 2, axis=0))
    if _available(log, (col.WRENCH_CONTACT, col.EXTERNAL_TRUE), "external_wrench_error_rms",
                  not_computed):
        est = log[col.wrench_columns(col.WRENCH_CONTACT)].to_numpy()
        ext = log[col.wrench_columns(col.EXTERNAL_TRUE)].to_numpy()
        ext_rms = (np.sqrt(np.mean((est[truth] - ext[truth]) ** 2, axis=0))
                   if truth.any() else np.full(6, np.nan))
        steady = truth.copy()
        for a, _ in true_eps:  # the touchdown transient: a spike the compensator sees late
            steady[(t >= t[a]) & (t < t[a] + TOUCHDOWN_S)] = False
        steady_rms = (np.sqrt(np.mean((est[steady] - ext[steady]) ** 2, axis=0))
                      if steady.any() else np.full(6, np.nan))
    return {
        "true_contacts": len(true_eps),
        "detected_contacts": len(det_eps),
        "detection_delay_s": delays[0] if len(delays) == 1 else (delays or None),
        "false_positives": int(false_pos),
        "missed_contacts": int(missed),
        "external_wrench_error_rms": _listed(ext_rms),
        "external_wrench_error_rms_after_touchdown": _listed(steady_rms),
        "compensation_error_rms": _listed(comp_rms),
        "compensation_error_over_noise": (None if comp_rms is None
                                          else (comp_rms / np.asarray(noise_std)).tolist()),
        "out_of_domain_fraction": float(log[col.OUT_OF_DOMAIN].mean()),
        "fault_samples": int(log[col.FAULT].sum()),
        "excluded_startup_samples": STARTUP_SAMPLES,
        **({"not_computed": not_computed} if not_computed else {}),
    }


# What evaluate_detection reads, and what produces it.
_CHAIN = ("the runtime chain's outputs: a station built with a compensator (simulate's log), "
          "add_recorder(..., chain=chain), or ftdrake.replay(model, log) passed as `replayed`")
INPUTS = {
    col.TIME: "the sample time, s (every log)",
    col.CONTACT_TRUE: ("the true contact flag: simulate's log, or add_recorder(..., "
                       "contact_true=port)"),
    col.CONTACT: _CHAIN, col.OUT_OF_DOMAIN: _CHAIN, col.FAULT: _CHAIN,
    col.WRENCH_CONTACT: _CHAIN, col.WRENCH_INTERNAL: _CHAIN,
    col.EXTERNAL_TRUE: ("the true contact wrench: simulate's log, or add_recorder(..., "
                        "wrench_contact_true=port)"),
    col.INTERNAL_TRUE: ("the true internal wrench (the reading without contact, noise and "
                        "drift): simulate's log"),
}


def _source(name: str) -> str:
    return INPUTS.get(name, INPUTS.get(name.rpartition("_")[0], ""))


def _require(log: pd.DataFrame, names) -> None:
    missing = [c for c in names if c not in log.columns]
    if missing:
        raise LogError("evaluate_detection: the log lacks " + "; ".join(
            f"{c!r} ({_source(c)})" for c in missing))


def _available(log: pd.DataFrame, prefixes, metric: str, not_computed: dict) -> bool:
    missing = [c for p in prefixes for c in col.wrench_columns(p) if c not in log.columns]
    if missing:
        groups = sorted({c.rpartition("_")[0] for c in missing})
        not_computed[metric] = "; ".join(f"no {g}_* columns ({_source(g)})" for g in groups)
    return not missing


def _with_replay(log: pd.DataFrame, replayed: pd.DataFrame | None) -> pd.DataFrame:
    """`log` with `replayed`'s chain outputs in place of its own (same rows)."""
    if replayed is None:
        return log
    if len(replayed) != len(log) or (
            col.TIME in replayed and not np.allclose(replayed[col.TIME], log[col.TIME])):
        raise LogError(f"evaluate_detection: `replayed` has {len(replayed)} rows, the log "
                       f"{len(log)}; replay the same log (ftdrake.replay(model, log))")
    outputs = [c for c in replayed.columns if c != col.TIME]
    return pd.concat([log.drop(columns=[c for c in outputs if c in log.columns]),
                      replayed[outputs].reset_index(drop=True).set_axis(log.index)], axis=1)


def _listed(values):
    return None if values is None else values.tolist()


def _episodes(flags: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of runs of True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2], strict=True))
