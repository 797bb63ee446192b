"""The learned two-part compensation as one file, and its reference correction exported.

:class:`TwoPartModel` holds what :mod:`ftdrake.experiments.contour` learns for one method:
part one, the torque feedforward GP (:mod:`ftdrake.systems.learned_feedforward`; may be
absent), and part two, the motor-reference correction GP
(:mod:`ftdrake.experiments.reference_correction`), with the confidence rule and the
reference's low-pass. Applied to a new path (a joint trajectory ``q_d(t)``) it gives the
torque feedforward system and the corrected reference, exactly as the experiment builds them.

File (:meth:`TwoPartModel.save`, written atomically; :meth:`TwoPartModel.load`)::

    FTDRAKE-TWO-PART\\n              magic line
    {"format_version": 1, ...}\\n    manifest: one line of JSON (its settings, part sizes)
    <bytes>                          each part, a complete model file (save_model's format)
    <32 bytes>                       SHA-256 of everything above

Export (:func:`export_reference_csv`): for a controller that takes a corrected joint path
but no torque feedforward (most industrial controllers), the corrected reference along a
path at the controller's rate, with the correction's std alongside. Columns: ``time`` (s),
``q_ref_j`` (rad, the corrected reference), ``offset_j`` (rad, ``q_ref − q_d``),
``offset_std_j`` (rad: the confidence times the GP's std σ of the offset, noise excluded)
and ``confidence_j`` (in [0, 1]), for each joint j. The offsets are those of the reference
the experiment runs (the 100 Hz knot spline of the filtered correction), sampled at the rate.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from pydrake.trajectories import PiecewisePolynomial

from ..compensation.files.persistence import load_model, save_model
from ..control.ilc import q_filter
from ..errors import LogError, ModelFileError
from ..io import atomic_path, atomic_write_bytes
from ..systems.learned_feedforward import LearnedFeedforward, check_feedforward_model
from .reference_correction import ReferenceCorrection, corrected_reference, desired_states

MAGIC = b"FTDRAKE-TWO-PART\n"
FORMAT_VERSION = 1
_DIGEST = 32
PARTS = ("feedforward", "reference")


class TwoPartModel:
    """Part one (torque GP, or None) and part two (reference GP) with their settings.

    `trust_ratio`/`reject_ratio`: the confidence rule of both parts; `reference_cutoff_hz`:
    the zero-phase low-pass of the reference offsets on the knots (0: none); `knot_dt`: the
    corrected reference's knot spacing (s); `info`: JSON-ready notes kept in the file.
    """

    def __init__(self, reference_model, feedforward_model=None, *, trust_ratio: float = 0.5,
                 reject_ratio: float = 0.9, reference_cutoff_hz: float = 5.0,
                 knot_dt: float = 0.01, info: dict | None = None):
        check_feedforward_model(reference_model)
        if feedforward_model is not None:
            check_feedforward_model(feedforward_model, reference_model.n_joints_)
        self.reference_model, self.feedforward_model = reference_model, feedforward_model
        self.trust_ratio, self.reject_ratio = float(trust_ratio), float(reject_ratio)
        self.reference_cutoff_hz, self.knot_dt = float(reference_cutoff_hz), float(knot_dt)
        self.info = dict(info or {})
        self.n = int(reference_model.n_joints_)
        self.correction = ReferenceCorrection(reference_model, trust_ratio=trust_ratio,
                                              reject_ratio=reject_ratio)

    @classmethod
    def from_learner(cls, learner, info: dict | None = None) -> TwoPartModel:
        """The model a :class:`~ftdrake.experiments.contour.Learner` of a two-part method
        holds after its iterations."""
        if learner.reference_model is None:
            raise ModelFileError(f"method {learner.method!r} learned no reference correction "
                                 "(only 'timed' and 'contour' are two-part)")
        plan = learner.plan
        return cls(learner.reference_model, learner.torque_model,
                   trust_ratio=plan.trust_ratio, reject_ratio=plan.reject_ratio,
                   reference_cutoff_hz=plan.reference_cutoff_hz,
                   info={"method": learner.method, **(info or {})})

    # -- applied to a path ----------------------------------------------------------------
    def feedforward(self) -> LearnedFeedforward | None:
        """Part one as a Drake system (None without part one)."""
        if self.feedforward_model is None:
            return None
        return LearnedFeedforward(self.feedforward_model, n_joints=self.n,
                                  trust_ratio=self.trust_ratio, reject_ratio=self.reject_ratio)

    def _offset_at(self, trajectory):
        def offset(t):
            c = self.correction.evaluate(desired_states(trajectory, t))[0]
            cutoff = self.reference_cutoff_hz
            return q_filter(c, float(t[1] - t[0]), cutoff) if cutoff > 0 else c
        return offset

    def reference(self, trajectory):
        """The corrected reference ``q_d + c`` (a C² spline on knots every ``knot_dt``) for
        the joint trajectory `trajectory` (a PiecewisePolynomial q_d(t), rad)."""
        return corrected_reference(trajectory, self._offset_at(trajectory),
                                   knot_dt=self.knot_dt)

    def reference_table(self, trajectory, rate_hz: float) -> pd.DataFrame:
        """The export's table (module docstring) along `trajectory` every ``1 / rate_hz`` s."""
        if not np.isfinite(rate_hz) or rate_hz <= 0:
            raise ValueError(f"rate_hz: must be > 0, got {rate_hz}")
        t = np.arange(trajectory.start_time(), trajectory.end_time() + 1e-9, 1.0 / rate_hz)
        q_d = trajectory.vector_values(t).T
        q_ref = self.reference(trajectory).vector_values(t).T
        _, std, confidence = self.correction.evaluate(desired_states(trajectory, t))
        columns = {"time": t}
        for name, values in (("q_ref", q_ref), ("offset", q_ref - q_d),
                             ("offset_std", confidence * std), ("confidence", confidence)):
            columns.update({f"{name}_{j}": values[:, j] for j in range(self.n)})
        return pd.DataFrame(columns)

    # -- the file ---------------------------------------------------------------------------
    def save(self, path) -> Path:
        """Writes the model to `path` atomically (module docstring's format)."""
        parts = {}
        with tempfile.TemporaryDirectory() as folder:
            for name, model in (("feedforward", self.feedforward_model),
                                ("reference", self.reference_model)):
                if model is None:
                    continue
                unit = "N*m" if name == "feedforward" else "rad"
                file = save_model(model, Path(folder) / f"{name}.ftd",
                                  target_names=[f"{name}_{j}" for j in range(self.n)],
                                  target_units=[unit] * self.n, sensor_frame="joints",
                                  extra={"kind": f"two_part_{name}"})
                parts[name] = file.read_bytes()
        manifest = {"format_version": FORMAT_VERSION, "kind": "two_part_compensation",
                    "n_joints": self.n, "trust_ratio": self.trust_ratio,
                    "reject_ratio": self.reject_ratio,
                    "reference_cutoff_hz": self.reference_cutoff_hz, "knot_dt": self.knot_dt,
                    "parts": {k: len(v) for k, v in parts.items()}, "info": self.info}
        body = (MAGIC + json.dumps(manifest, allow_nan=False, separators=(",", ":")).encode()
                + b"\n" + b"".join(parts[k] for k in PARTS if k in parts))
        path = Path(path)
        atomic_write_bytes(path, body + hashlib.sha256(body).digest())
        return path

    @classmethod
    def load(cls, path) -> TwoPartModel:
        """The model saved at `path`; ModelFileError names the file and what is wrong."""
        path = Path(path)
        if not path.is_file():
            raise ModelFileError(f"{path}: no such two-part model file")
        data = path.read_bytes()
        if not data.startswith(MAGIC):
            raise ModelFileError(f"{path}: not a two-part model file (learn one with "
                                 "`learn-feedforward --two-part --save-model FILE`)")
        body, digest = data[:-_DIGEST], data[-_DIGEST:]
        if hashlib.sha256(body).digest() != digest:
            raise ModelFileError(f"{path}: checksum mismatch (the file is truncated or was "
                                 "edited)")
        end = body.index(b"\n", len(MAGIC))
        manifest = json.loads(body[len(MAGIC):end])
        if manifest.get("format_version") != FORMAT_VERSION:
            raise ModelFileError(f"{path}: format version {manifest.get('format_version')} "
                                 f"is not readable (this ftdrake reads {FORMAT_VERSION})")
        models, offset = {}, end + 1
        with tempfile.TemporaryDirectory() as folder:
            for name in PARTS:
                size = manifest["parts"].get(name)
                if size is None:
                    continue
                part = Path(folder) / f"{name}.ftd"
                part.write_bytes(body[offset:offset + size])
                offset += size
                try:
                    models[name] = load_model(part, expect_n_joints=manifest["n_joints"])
                except ModelFileError as e:
                    raise ModelFileError(f"{path}: its {name} part: {e}") from None
        if "reference" not in models:
            raise ModelFileError(f"{path}: holds no reference correction")
        return cls(models["reference"], models.get("feedforward"),
                   trust_ratio=manifest["trust_ratio"], reject_ratio=manifest["reject_ratio"],
                   reference_cutoff_hz=manifest["reference_cutoff_hz"],
                   knot_dt=manifest["knot_dt"], info=manifest.get("info"))


def read_joint_path(path, n_joints: int):
    """A joint path from the CSV `path` (columns ``time`` (s) and ``q_0 … q_{n-1}`` (rad), at
    least 4 rows, time increasing) as a C² spline at rest at both ends."""
    path = Path(path)
    if not path.is_file():
        raise LogError(f"{path}: no such joint path file")
    frame = pd.read_csv(path, comment="#", skipinitialspace=True)
    names = ["time", *(f"q_{j}" for j in range(n_joints))]
    missing = [c for c in names if c not in frame.columns]
    if missing:
        raise LogError(f"{path}: the joint path lacks column(s) {missing} (need time, q_0 … "
                       f"q_{n_joints - 1} for the model's {n_joints} joints)")
    values = frame[names].to_numpy(dtype=float)
    if len(values) < 4 or not np.isfinite(values).all():
        raise LogError(f"{path}: need >= 4 rows of finite numbers, got {len(values)} rows")
    if (np.diff(values[:, 0]) <= 0).any():
        row = int(np.flatnonzero(np.diff(values[:, 0]) <= 0)[0]) + 2
        raise LogError(f"{path}: time must increase strictly (row {row})")
    zero = np.zeros((n_joints, 1))
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        values[:, 0], values[:, 1:].T, zero, zero)


def export_reference_csv(model: TwoPartModel, trajectory, rate_hz: float,
                         path) -> pd.DataFrame:
    """Writes :meth:`TwoPartModel.reference_table` to the CSV `path` atomically (every digit
    of each number); returns the table."""
    table = model.reference_table(trajectory, rate_hz)
    with atomic_path(path) as tmp:
        table.to_csv(tmp, index=False, float_format="%.17g")
    return table


def read_reference_csv(path, n_joints: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time (N,), offset (N, n), offset_std (N, n)) from an exported correction CSV."""
    frame = pd.read_csv(path)
    names = ["time", *(f"offset_{j}" for j in range(n_joints)),
             *(f"offset_std_{j}" for j in range(n_joints))]
    missing = [c for c in names if c not in frame.columns]
    if missing:
        raise LogError(f"{path}: lacks column(s) {missing}; not an exported correction for "
                       f"{n_joints} joints")
    values = frame[names].to_numpy(dtype=float)
    return values[:, 0], values[:, 1:n_joints + 1], values[:, n_joints + 1:]


def offset_from_csv(path, n_joints: int):
    """``offset_at(t)`` (times (N,) → (N, n) rad) interpolating an exported correction (zero
    outside it): what a controller replaying the CSV adds to its path, for
    :func:`~ftdrake.experiments.reference_correction.corrected_reference`."""
    t, offset, _ = read_reference_csv(path, n_joints)

    def at(times):
        return np.column_stack([np.interp(times, t, offset[:, j], left=0.0, right=0.0)
                                for j in range(n_joints)])
    return at


__all__ = ["TwoPartModel", "export_reference_csv", "offset_from_csv", "read_joint_path",
           "read_reference_csv"]
