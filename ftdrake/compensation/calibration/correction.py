"""The gain/cross-talk correction of a wrist F/T sensor, identified from static poses.

A 6 × 6 correction ``C`` (iCub's "secondary calibration matrix") with
``W_S ≈ C·(W_meas − b − k·ΔT)``, identified by linear least squares from the wrench each pose
should give, ``W_S = [m·g_S; m·c × g_S]`` (:func:`true_wrench`; gravity known, the payload
known or identified): the reading is ``M·W_S + b (+ k·ΔT)`` with ``M = C⁻¹``, linear in M and
b. ``"block"`` fits forces from forces and torques from torques (two 3 × 3 blocks),
``"full"`` all 36 entries. What the data determine depends on the loads:

* one load (the tool): its torques are all ⊥ its centre of mass (``T = c × F``), so the torque
  correction along c is not determined, and in ``"full"`` the forces and torques are tied
  (three directions free; the fit is then the general linear model of that load, which
  predicts its readings best); the force block is determined, as its effective value for
  this load (``M_FF + M_FT·[c]×``: the torque-to-force cross-talk folded in);
* without a known payload, the mean force gain cannot be told from the mass (the identified
  mass absorbs it) nor the torque gain from the centre of mass;
* the full 6 × 6 needs at least three known loads whose centres of mass are not on one line.

Directions the data leave free are kept at the identity (no correction: the least-change
solution) and their entries get an infinite standard error; an
:class:`~..identification.payload_report.ExcitationWarning` names them. The standard errors of
C come from those of M by the delta method (``dC = −C·dM·C``), rows of M independent, the
payload taken as exact.
:mod:`.calibration` calls :func:`identify_correction` for ``calibrate --correction``.
"""

from __future__ import annotations

import dataclasses as dc
import warnings

import numpy as np

from ...conventions import WRENCH_AXES
from ...errors import ConfigError
from ..identification.payload_report import ExcitationWarning

#: Structures of the gain/cross-talk correction C: two 3 × 3 blocks, or all of the 6 × 6.
CORRECTIONS = ("block", "full")
#: A singular value below this fraction of the largest is a direction the data do not span.
_RANK_TOL = 1e-6
#: What determines the entries one load leaves free.
MORE_LOADS = ("poses with other known loads (columns known_mass, known_com_x/y/z; centres of "
              "mass not on one line for the full 6 × 6) determine them")
SEVERAL_LOADS = ("the table holds {} loads: the payload and biases above are one gravity + bias "
                 "fit over all of them (not a payload); the correction uses the known ones")


@dc.dataclass
class CalibrationCorrection:
    """The sensor's gain/cross-talk correction identified from static poses.

    ``matrix`` C (6 × 6, dimensionless between like axes, 1/m from torque to force and m from
    force to torque): ``W_S ≈ C·(W_meas − bias − k·ΔT)``, the wrench in the model's frame S
    (a mounting rotation included) from a reading; ``sensor_matrix`` M = C⁻¹ (the reading per
    true wrench). ``std_errors`` / ``sensor_std_errors``: their standard errors (∞ where the
    data do not determine an entry; 0 where the structure fixes it). ``bias`` and
    ``temperature_coefficients`` are re-identified with it. ``payload`` ``[m, m·cx, m·cy,
    m·cz]`` is the one the true wrench was computed with (None with one per row);
    ``residual_rms`` the fit's per axis, ``rigid_residual_rms`` the gravity + bias model's.
    ``free_directions`` (k × 6, unit rows): wrench directions the data do not span, along which
    C is not determined (``undetermined`` says the same in words).
    """

    structure: str
    matrix: np.ndarray
    std_errors: np.ndarray
    sensor_matrix: np.ndarray
    sensor_std_errors: np.ndarray
    bias: np.ndarray
    bias_std_errors: np.ndarray
    residual_rms: np.ndarray
    rigid_residual_rms: np.ndarray
    condition_number: float
    rank: tuple
    undetermined: list
    known_payload: bool
    loads: int
    payload: np.ndarray | None = None
    temperature_reference: float | None = None
    temperature_coefficients: np.ndarray | None = None
    temperature_std_errors: np.ndarray | None = None
    free_directions: np.ndarray = dc.field(default_factory=lambda: np.zeros((0, 6)))
    #: (6, 3) what one load's poses do determine when C is not: the reading per unit gravity
    #: in S, ``K = M·[m·I; [h]×]`` (N per m/s², N·m per m/s²), and its standard errors; None
    #: with several loads or a payload per row.
    gravity_matrix: np.ndarray | None = None
    gravity_matrix_std_errors: np.ndarray | None = None

    def reading(self, W_S: np.ndarray, temperature=None) -> np.ndarray:
        """(N, 6) readings for true wrenches `W_S` (N, 6) in S: ``M·W + b (+ k·ΔT)``."""
        out = W_S @ self.sensor_matrix.T + self.bias
        if self.temperature_coefficients is not None and temperature is not None:
            out = out + np.outer(np.asarray(temperature) - self.temperature_reference,
                                 self.temperature_coefficients)
        return out

    def free_entries(self) -> np.ndarray:
        """(6, 6) bool: the entries of C these poses do not determine (a change of the
        sensor matrix along a direction the loads' wrenches do not span moves them)."""
        return ~np.isfinite(self.std_errors)

    def to_dict(self) -> dict:
        table = {
            "structure": self.structure,
            "matrix": self.matrix.tolist(),
            "std_errors": self.std_errors.tolist(),
            "meaning": ("C: wrench in S = C·(reading − bias − k·ΔT); rows and columns Fx, Fy, "
                        "Fz, Tx, Ty, Tz (torque-to-force entries in 1/m, force-to-torque in m)"),
            "sensor_matrix": self.sensor_matrix.tolist(),
            "sensor_std_errors": self.sensor_std_errors.tolist(),
            "bias": dict(zip(WRENCH_AXES, self.bias.tolist(), strict=True)),
            "bias_std_errors": dict(zip(WRENCH_AXES, self.bias_std_errors.tolist(),
                                        strict=True)),
            "residual_rms": dict(zip(WRENCH_AXES, self.residual_rms.tolist(), strict=True)),
            "residual_rms_gravity_and_bias_only": dict(zip(
                WRENCH_AXES, self.rigid_residual_rms.tolist(), strict=True)),
            "condition_number": float(self.condition_number),
            "rank": list(self.rank),
            "loads": self.loads,
            "payload": ("known (given)" if self.known_payload else
                        "identified from these poses: the mean force gain is absorbed in the "
                        "mass, the torque gain in the centre of mass"),
            "not_determined": list(self.undetermined) or "none",
            "not_determined_entries": ([f"C[{WRENCH_AXES[a]},{WRENCH_AXES[b]}]"
                                        for a, b in zip(*np.nonzero(self.free_entries()),
                                                        strict=True)] or "none"),
        }
        if self.loads > 1:
            table["note"] = SEVERAL_LOADS.format(self.loads)
        if self.temperature_coefficients is not None:
            table["temperature_coefficients_per_k"] = dict(zip(
                WRENCH_AXES, self.temperature_coefficients.tolist(), strict=True))
        return table

    def summary(self) -> list[str]:
        how = {"block": "force and torque 3 × 3 blocks", "full": "full 6 × 6"}[self.structure]
        payload = ("known payload" if self.known_payload else
                   "payload identified from the same poses (mean force gain absorbed in the "
                   "mass)")
        lines = [(f"  gain/cross-talk correction C ({how}; {self.loads} load(s), {payload}; "
                  f"condition number {self.condition_number:.3g}):"),
                 ("    wrench in S = C·(reading − bias), rows/columns Fx..Tz; entry ± std "
                  "error (· fixed at 0 by the structure; 'free': not determined by these "
                  "poses, the least-change value)")]
        fixed = (self.sensor_std_errors == 0) & (self.sensor_matrix == 0)
        free = self.free_entries()
        for i, axis in enumerate(WRENCH_AXES):
            lines.append(f"    {axis}: " + "  ".join(
                f"{'·':^18s}" if fixed[i, j] else
                f"{v:+.5f} {'free':7s}  " if free[i, j] else f"{v:+.5f} ± {_se(e):7s}"
                for j, (v, e) in enumerate(zip(self.matrix[i], self.std_errors[i],
                                               strict=True))))
        if free.any():
            lines.append(f"    not determined by these poses ({int(free.sum())} of "
                         f"{int((~fixed).sum())} entries): {name_entries(free)}; "
                         f"{MORE_LOADS}")
            if self.gravity_matrix is not None:
                lines.append("    what these poses determine: the reading per unit gravity "
                             "in S, K = M·[m·I; [h]×] (columns gx, gy, gz):")
                for i, axis in enumerate(WRENCH_AXES):
                    lines.append(f"    {axis}: " + "  ".join(
                        f"{v:+.5g} ± {_se(e):7s}" for v, e in zip(
                            self.gravity_matrix[i], self.gravity_matrix_std_errors[i],
                            strict=True)))
        lines.append("    residual RMS (Fx..Tz): " + ", ".join(
            f"{r:.3g}" for r in self.residual_rms) + "; gravity + bias only: " + ", ".join(
            f"{r:.3g}" for r in self.rigid_residual_rms))
        for note in self.undetermined:
            lines.append(f"    not determined: {note}")
        if self.loads > 1:
            lines.append(f"    note: {SEVERAL_LOADS.format(self.loads)}")
        return lines


def identify_correction(W_S, Y, structure="block", temperature=None,
                        rigid_residual_rms=None, *, known_payload=False, loads=1,
                        payload=None) -> CalibrationCorrection:
    """Fits ``Y ≈ M·W_S + b (+ k·ΔT)`` by linear least squares; C = M⁻¹ (module docstring).

    `W_S` (N, 6): the wrench each pose should give in S (gravity on the payload); `Y` (N, 6)
    the readings; `temperature` (N,) °C or None. Each row of M is one least-squares problem
    on the design ``[W_S (its block's columns), 1, ΔT]``, columns scaled to unit RMS; the
    deviation from the identity is the minimum-norm solution, so directions the design does
    not span (singular values below 1e-6 of the largest) stay uncorrected and their entries
    get an infinite standard error.
    """
    if structure not in CORRECTIONS:
        raise ConfigError(f"correction must be one of {list(CORRECTIONS)}, got {structure!r}")
    W_S, Y = np.asarray(W_S, float), np.asarray(Y, float)
    reference, d = temperature_deviation(temperature)
    groups = ([[0, 1, 2], [3, 4, 5]] if structure == "block" else [list(range(6))])
    M, M_se = np.eye(6), np.zeros((6, 6))
    bias, bias_se = np.zeros(6), np.zeros(6)
    k, k_se = np.zeros(6), np.zeros(6)
    residual = np.empty_like(Y)
    per_row = {}  # row i → (its columns, covariance of its M entries, null directions)
    ranks, conditions, undetermined, free_directions = [], [], [], []
    for cols in groups:
        nc = len(cols)
        D = np.column_stack([W_S[:, cols], np.ones(len(Y))] + ([] if d is None else [d]))
        scale = np.sqrt(np.mean(D ** 2, axis=0))
        scale[scale == 0] = 1.0
        U, S, Vt = np.linalg.svd(D / scale, full_matrices=False)
        r = int(np.sum(S > _RANK_TOL * S[0]))
        ranks.append(r)
        conditions.append(float(S[0] / S[r - 1]))
        target = Y[:, cols] - W_S[:, cols]  # the deviation from the identity
        coef = (Vt[:r].T @ ((U[:, :r].T @ target) / S[:r, None])) / scale[:, None]
        residual[:, cols] = target - D @ coef
        sigma2 = np.sum(residual[:, cols] ** 2, axis=0) / max(len(Y) - r, 1)
        unit = Vt[:r].T / S[:r]
        unit = (unit @ unit.T) / np.outer(scale, scale)  # (DᵀD)⁺ in the original units
        null = (Vt[r:].T / scale[:, None])  # null directions of D, original units
        free = np.linalg.norm(Vt[r:].T, axis=1) > 1e-6 if r < D.shape[1] else \
            np.zeros(D.shape[1], bool)
        se_unit = np.where(free, np.inf, np.sqrt(np.maximum(np.diag(unit), 0.0)))
        for row, i in enumerate(cols):
            # A free entry's error is ∞ even where the fit leaves no residual (0 · ∞).
            se = np.where(np.isinf(se_unit), np.inf, np.sqrt(sigma2[row]) * np.where(
                np.isinf(se_unit), 0.0, se_unit))
            M[i, cols] += coef[:nc, row]
            M_se[i, cols] = se[:nc]
            bias[i], bias_se[i] = coef[nc, row], se[nc]
            if d is not None:
                k[i], k_se[i] = coef[nc + 1, row], se[nc + 1]
            per_row[i] = (cols, sigma2[row] * unit[:nc, :nc], null[:nc])
        if r < D.shape[1]:
            undetermined.append(_describe_null(cols, null[:nc]))
            for v in null[:nc].T:
                if np.linalg.norm(v) > 0:
                    direction = np.zeros(6)
                    direction[cols] = v / np.linalg.norm(v)
                    free_directions.append(direction)
    C = np.linalg.inv(M)
    C_se = _inverse_std_errors(C, per_row)
    K = K_se = None
    if free_directions and payload is not None and np.ndim(payload) == 1:
        K, K_se = _gravity_matrix(M, per_row, payload)
    if undetermined:
        warnings.warn(
            "the poses do not determine the whole gain/cross-talk correction: "
            + "; ".join(undetermined) + ". The correction leaves those directions as they are "
            "(the least change; their entries print as 'free'), which does not change these "
            "poses' readings: it still corrects this payload's readings, not necessarily other "
            "loads'; poses with other known loads (columns known_mass, known_com_x/y/z) "
            "determine them", ExcitationWarning, stacklevel=3)
    return CalibrationCorrection(
        structure=structure, matrix=C, std_errors=C_se, sensor_matrix=M,
        sensor_std_errors=M_se, bias=bias, bias_std_errors=bias_se,
        residual_rms=np.sqrt(np.mean(residual ** 2, axis=0)),
        rigid_residual_rms=(np.full(6, np.nan) if rigid_residual_rms is None
                            else np.asarray(rigid_residual_rms, float)),
        condition_number=max(conditions), rank=tuple(ranks), undetermined=undetermined,
        known_payload=known_payload, loads=int(loads),
        payload=None if payload is None else np.asarray(payload, float),
        temperature_reference=reference if d is not None else None,
        temperature_coefficients=k if d is not None else None,
        temperature_std_errors=k_se if d is not None else None,
        free_directions=np.array(free_directions).reshape(-1, 6),
        gravity_matrix=K, gravity_matrix_std_errors=K_se)


def _gravity_matrix(M, per_row, payload):
    """(K, its standard errors), K = M·L with W_S = L·g_S, L = [m·I; [h]×]: determined
    even where M is not (M's free part is orthogonal to L's columns, the wrenches' span)."""
    m, h = payload[0], np.asarray(payload[1:4], float)
    L = np.vstack([m * np.eye(3), np.array([[0, -h[2], h[1]], [h[2], 0, -h[0]],
                                             [-h[1], h[0], 0]])])
    K, K_se = M @ L, np.zeros((6, 3))
    for i, (cols, cov, _) in per_row.items():
        Li = L[cols]
        K_se[i] = np.sqrt(np.maximum(np.diag(Li.T @ cov @ Li), 0.0))
    return K, K_se


def uncorrected_rms(residual, temperature) -> np.ndarray:
    """Per-axis RMS of `residual` after the best constant (and temperature slope)."""
    _, d = temperature_deviation(temperature)
    D = np.ones((len(residual), 1)) if d is None else np.column_stack([np.ones(len(d)), d])
    coef, *_ = np.linalg.lstsq(D, residual, rcond=None)
    return np.sqrt(np.mean((residual - D @ coef) ** 2, axis=0))


def _inverse_std_errors(C, per_row) -> np.ndarray:
    """Standard errors of C = M⁻¹ from those of M's rows (independent): dC = −C·dM·C, so
    var(C_ab) = Σ_i C_ai² · c_bᵀ Σ_i c_b with c_b column b of C on row i's columns; ∞ where
    a direction row i's data leave free moves C_ab."""
    se = np.zeros((6, 6))
    for b in range(6):
        for a in range(6):
            var, free = 0.0, False
            for i, (cols, cov, null) in per_row.items():
                if abs(C[a, i]) < 1e-12:
                    continue
                c = C[cols, b]
                var += C[a, i] ** 2 * float(c @ cov @ c)
                if null.size and np.any(np.abs(null.T @ c) > 1e-6 * np.linalg.norm(c)
                                        * np.linalg.norm(null, axis=0)):
                    free = True
            se[a, b] = np.inf if free else np.sqrt(max(var, 0.0))
    return se


def _describe_null(cols, null) -> str:
    """A sentence naming the wrench directions a block's data do not span."""
    names = [WRENCH_AXES[c] for c in cols]
    parts = []
    for v in null.T:
        if np.linalg.norm(v) == 0:
            continue
        v = v / np.linalg.norm(v)
        v = v * np.sign(v[np.argmax(np.abs(v))])
        parts.append("(" + ", ".join(f"{n} {x:+.2f}" for n, x in zip(names, v, strict=True)
                                     if abs(x) >= 0.005) + ")")
    what = ("torque" if cols[0] == 3 else "force") if len(cols) == 3 else "wrench"
    why = ("one load's torques are all perpendicular to its centre of mass"
           if what == "torque" else "the loads' forces and torques are tied (T = c × F)")
    return (f"the {what} correction along {len(parts)} direction(s) "
            f"{', '.join(parts)} ({why})")


def true_wrench(g_S: np.ndarray, payload: np.ndarray) -> np.ndarray:
    """(N, 6) wrench ``[m·g_S; h × g_S]`` a payload at rest puts on the sensor, in S.

    `g_S` (N, 3) gravity in S (m/s²); `payload` ``[m, h]`` (4,) or one per row (N, 4), with
    ``h = m·c`` the first moment (kg·m) about So.
    """
    payload = np.broadcast_to(np.asarray(payload, float), (len(g_S), 4))
    return np.hstack([payload[:, :1] * g_S, np.cross(payload[:, 1:], g_S)])


def name_entries(free: np.ndarray) -> str:
    """The free entries of C in words: whole columns by name (a wrench axis no pose loads
    independently), the rest as C[row,column]."""
    parts = []
    for b, axis in enumerate(WRENCH_AXES):
        rows = np.flatnonzero(free[:, b])
        if not len(rows):
            continue
        if len(rows) >= 3 and (set(rows) >= {0, 1, 2} or set(rows) >= {3, 4, 5}):
            which = ("all rows" if len(rows) == 6 else
                     "rows " + "..".join((WRENCH_AXES[rows[0]], WRENCH_AXES[rows[-1]])))
            parts.append(f"column {axis} ({which})")
        else:
            parts.extend(f"C[{WRENCH_AXES[a]},{axis}]" for a in rows)
    return ", ".join(parts)


def _se(e: float) -> str:
    return "∞" if not np.isfinite(e) else f"{e:.1e}"


def temperature_deviation(temperature):
    if temperature is None:
        return None, None
    reference = float(np.mean(temperature))
    d = temperature - reference
    return reference, (d if np.any(np.abs(d) > 1e-9) else None)
