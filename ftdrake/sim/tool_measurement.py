"""Tool-side measurements over a run's log, and the tool errors they give.

The encoders sit on the motor shafts, so the controller never sees the gearboxes' twist; the
tool has to be measured from outside. Two setups (the seed paper's §§ on end-effector
sensing):

* **Timed** (:func:`measure_timed`): the tool tip's position at known times, like a laser
  tracker streaming at a fixed rate (noise and latency configurable,
  :class:`~ftdrake.config.contour.TrackerConfig`). The tool error at a desired time is
  then ``p_desired(t) − p_measured(t)`` (:func:`timed_error`), all three components.
* **Untimed contour** (:func:`measure_contour`): the path the tool left in the cutting
  plane, as points along it without times, like an inspection of the cut afterwards
  (:class:`~ftdrake.config.contour.ContourScanConfig`). Only the deviation *normal* to the
  ideal path is observable: at each point of the ideal path, the signed distance along its
  normal to the measured contour (:func:`normal_deviation`, the mean over the nearest
  measured points). A lag along the path leaves no trace in a contour, and it does not
  spoil one either.

Positions are in W (m); in-plane coordinates in the plane's frame P (x, y in the plane, z its
normal), ``p_P = R_WPᵀ (p_W − p_WPo)``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ..config.contour import ContourScanConfig, TrackerConfig


def measure_timed(t, p_WTip, config: TrackerConfig) -> tuple[np.ndarray, np.ndarray]:
    """A tracker's samples of the tip positions `p_WTip` (N, 3), m, logged at times `t` (N,)
    (in the tracker's frame and on its clock when `config` mis-registers it:
    :func:`misregister_timed`).

    Returns ``(t_stamp, p_measured)``: samples taken every ``1 / rate_hz`` s from ``t[0]``
    (linear interpolation of the log), with white noise, and only those that arrived
    (``t_taken + latency <= t[-1]``); stamped with the time taken when
    ``stamp_corrected``, else with the arrival time.
    """
    config.validate()
    t, p = np.asarray(t, dtype=float), np.asarray(p_WTip, dtype=float)
    taken = np.arange(t[0], t[-1] - config.latency_s + 1e-12, 1.0 / config.rate_hz)
    sampled = np.column_stack([np.interp(taken, t, p[:, i]) for i in range(3)])
    rng = np.random.default_rng(config.seed)
    sampled += rng.normal(0.0, config.noise_std_m, sampled.shape)
    stamp = taken if config.stamp_corrected else taken + config.latency_s
    if config.misregistered:
        return misregister_timed(stamp, sampled, config)
    return stamp, sampled


def _rotation_matrix(rotation_vector) -> np.ndarray:
    return Rotation.from_rotvec(np.asarray(rotation_vector, dtype=float)).as_matrix()


def misregister_timed(stamp, p_W, config: TrackerConfig) -> tuple[np.ndarray, np.ndarray]:
    """Stamps (N,) on the controller's clock and positions (N, 3) in W as the tracker of
    `config` reports them: ``p_T = R_BTᵀ (p_W − p_BT)``, ``t_T = (1 + skew) t + offset``."""
    R_BT = _rotation_matrix(config.frame_rotation_rad)
    p = (np.asarray(p_W, dtype=float) - np.asarray(config.frame_offset_m, dtype=float)) @ R_BT
    return (1.0 + config.clock_skew) * np.asarray(stamp, dtype=float) + config.clock_offset_s, p


def measure_fiducials(config: TrackerConfig) -> tuple[np.ndarray, np.ndarray]:
    """(known in W, as the tracker measures them), each (K, 3), m: the tracker's fiducials
    with its noise (seed ``seed + 1``) in its frame."""
    known = np.asarray(config.fiducials_m, dtype=float)
    rng = np.random.default_rng(config.seed + 1)
    noisy = known + rng.normal(0.0, config.noise_std_m, known.shape)
    return known, misregister_timed(np.zeros(len(known)), noisy, config)[1]


def misregister_contour(points_P, config: ContourScanConfig) -> np.ndarray:
    """In-plane points (N, 2) in P as the instrument of `config` reports them,
    ``R(−θ) (p − offset)``."""
    c, s = np.cos(config.frame_rotation_rad), np.sin(config.frame_rotation_rad)
    R = np.array([[c, -s], [s, c]])
    return (np.asarray(points_P, dtype=float) - np.asarray(config.frame_offset_m)) @ R


def measure_datums(config: ContourScanConfig) -> tuple[np.ndarray, np.ndarray]:
    """(known in P, as the instrument measures them), each (K, 2), m: the part's datum
    points with the scan's noise (seed ``seed + 1``) in the instrument's frame."""
    known = np.asarray(config.datums_m, dtype=float)
    rng = np.random.default_rng(config.seed + 1)
    return known, misregister_contour(known + rng.normal(0.0, config.noise_std_m, known.shape),
                                      config)


def timed_error(t_desired, p_desired, t_stamp, p_measured) -> np.ndarray:
    """``p_desired − p_measured`` (N, 3), m, at the desired times (the measurement linearly
    interpolated to them; held at its ends)."""
    t_desired = np.asarray(t_desired, dtype=float)
    measured = np.column_stack([np.interp(t_desired, t_stamp, p_measured[:, i])
                                for i in range(3)])
    return np.asarray(p_desired, dtype=float) - measured


def to_plane(p_W, p_WPo, R_WP) -> np.ndarray:
    """Positions `p_W` (N, 3) in the plane's frame P: (N, 2) in-plane coordinates, m."""
    return ((np.asarray(p_W, dtype=float) - p_WPo) @ np.asarray(R_WP))[:, :2]


def resample_by_arc_length(points, spacing: float) -> np.ndarray:
    """Points every `spacing` (m) of arc length along the polyline `points` (N, d)."""
    points = np.asarray(points, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    at = np.arange(0.0, s[-1] + 1e-15, spacing)
    return np.column_stack([np.interp(at, s, points[:, i]) for i in range(points.shape[1])])


def measure_contour(p_P, config: ContourScanConfig) -> np.ndarray:
    """An untimed scan of the path `p_P` (N, 2) in the cutting plane: (M, 2) points, m,
    every ``spacing_m`` along it, each with white noise; no times (in the instrument's frame
    when `config` mis-registers it: :func:`misregister_contour`)."""
    config.validate()
    points = resample_by_arc_length(p_P, config.spacing_m)
    rng = np.random.default_rng(config.seed)
    points = points + rng.normal(0.0, config.noise_std_m, points.shape)
    return misregister_contour(points, config) if config.misregistered else points


def normal_deviation(ideal_P, normal_P, measured_P, *, neighbours: int = 5,
                     max_distance: float = 2e-3) -> np.ndarray:
    """Signed deviation (N,), m, of the measured contour from each ideal point along that
    point's unit normal (+ along the normal): the mean of ``n · (p_measured − p_ideal)``
    over the `neighbours` measured points nearest the normal line through it (the
    points' distance from the line decides, not their distance from the point; the normal
    offset, up to `max_distance`, is then what is measured). NaN where no measured point
    lies within `max_distance` of the ideal point.
    """
    ideal = np.asarray(ideal_P, dtype=float)
    normal = np.asarray(normal_P, dtype=float)
    measured = np.asarray(measured_P, dtype=float)
    tree = cKDTree(measured)
    k = min(max(4 * neighbours, 20), len(measured))
    distance, index = tree.query(ideal, k=k)
    out = np.full(len(ideal), np.nan)
    tangent = np.column_stack([-normal[:, 1], normal[:, 0]])
    for i in range(len(ideal)):
        near = index[i][distance[i] <= max_distance]
        if len(near) == 0:
            continue
        offset = measured[near] - ideal[i]
        along = np.abs(offset @ tangent[i])  # distance from the normal line
        pick = near[np.argsort(along)[:neighbours]]
        out[i] = ((measured[pick] - ideal[i]) @ normal[i]).mean()
    return out


__all__ = ["measure_contour", "measure_datums", "measure_fiducials", "measure_timed",
           "misregister_contour", "misregister_timed", "normal_deviation",
           "resample_by_arc_length", "timed_error", "to_plane"]
