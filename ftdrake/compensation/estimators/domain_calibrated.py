"""A hybrid whose out-of-domain std is calibrated on held-out rows: a wrapping estimator.

As scikit-learn's ``CalibratedClassifierCV`` wraps a classifier, :class:`DomainCalibratedHybrid`
wraps a :class:`~.hybrid.HybridCompensator` and calibrates how its std grows away from its
training data (ℓ, g and optionally σ²_in and c, :mod:`.domain`) on rows the hybrid was not
fitted on. The wrapped hybrid is never changed: the calibrated terms are the wrapper's own
fitted attributes, set in its ``fit``, under the names the hybrid predicts with
(``domain_length_``, ``domain_growth_``, ``domain_parameter_scale_``, ``domain_excess_var_``,
``residual_noise_var_``); every other fitted attribute (``physics_``, ``residual_``,
``n_joints_``, ``wrench_delay_s_``, ...) is read from the fitted hybrid, ``estimator_``. So
the wrapper predicts, runs in the loop and is saved like a hybrid.

Two ways, as ``CalibratedClassifierCV``'s ``cv``:

- ``holdout=None``: `estimator` is a fitted hybrid, used as it is; ``fit(X, y)`` are the
  calibration rows (another contact-free log of the task's motion).
- ``holdout=share``: ``fit(X, y, groups)`` holds out the runs farthest from the others
  (:func:`.domain.farthest_groups`) until `share` of the rows is held out, fits a clone of
  `estimator` on the rest and calibrates on them; with `refit` the clone is then fitted on all
  rows and keeps the calibrated ℓ and g (and with ``in_domain="held_out"`` c and σ²_in's
  excess over its training error).
"""

from __future__ import annotations

import numpy as np
from sklearn.base import clone
from sklearn.utils.validation import check_is_fitted

from ..evaluation.metrics import coverage
from ..features import check_feature_set
from . import domain
from .hybrid import HybridCompensator, default_residual

# The calibrated terms: the hybrid's attribute names (what it predicts with).
_TERMS = ("domain_length_", "domain_growth_", "domain_parameter_scale_", "domain_excess_var_",
          "residual_noise_var_")


class DomainCalibratedHybrid(HybridCompensator):
    """A hybrid with its out-of-domain std calibrated on held-out rows (module docstring).

    Parameters
    ----------
    estimator : HybridCompensator with a forest residual (the support term's std); fitted
        when `holdout` is None (default: an unfitted ``HybridCompensator()``).
    holdout : None (`estimator` is fitted; ``fit``'s rows are the calibration rows) or the
        share in (0, 0.5) of ``fit``'s rows held out for the calibration (whole runs).
    refit : with `holdout`: fit `estimator` again on all rows after the calibration.
    shared_growth : one growth of the std for all axes, in units of each axis' σ²_far
        (default one per axis; :func:`.domain.calibrate`).
    in_domain : ``"cross_fit"`` (σ²_in and c = 1 from the hybrid's fit) or ``"held_out"``
        (fitted on the held-out rows too); :data:`.domain.IN_DOMAIN_SOURCES`.

    Fitted attributes: ``estimator_`` (the fitted hybrid: `estimator` itself when `holdout`
    is None), the calibrated terms ``domain_length_`` ℓ (∞: residual weighted 1 everywhere),
    ``domain_growth_`` g (k,), ``domain_parameter_scale_`` c, and with a calibrated level
    ``domain_excess_var_`` and ``residual_noise_var_`` σ²_in (k,); ``domain_calibration_``,
    what a manifest keeps: the rows, ℓ (None: ∞), g, c, σ_in, and the 95 % coverage per axis
    on the calibration rows before and after (held-out groups and their median distance
    with `holdout`); ``wrench_delay_s_`` (s, :meth:`~.base.Compensator.fit`).
    """

    def __init__(self, estimator=None, holdout: float | None = None, refit: bool = True,
                 shared_growth: bool = False, in_domain: str = "cross_fit"):
        self.estimator = estimator
        self.holdout = holdout
        self.refit = refit
        self.shared_growth = shared_growth
        self.in_domain = in_domain

    def __getattr__(self, name: str):
        """The fitted hybrid's attribute `name` (called only when the wrapper has none)."""
        if name.startswith("__") or name in ("estimator_", "estimator"):
            raise AttributeError(name)
        try:
            inner = object.__getattribute__(self, "estimator_")
        except AttributeError:
            raise AttributeError(
                f"{type(self).__name__} has no attribute {name!r} (not fitted)") from None
        return getattr(inner, name)

    def fit(self, X, y, groups=None, *, wrench_delay_s: float | None = None):
        """Calibrates on `X`, `y` (``holdout=None``) or fits and calibrates on held-out runs of
        them (`groups`: a run label per row, or None for contiguous time blocks). Returns
        self."""
        if self.in_domain not in domain.IN_DOMAIN_SOURCES:
            raise ValueError(f"in_domain must be one of {domain.IN_DOMAIN_SOURCES}; got "
                             f"{self.in_domain!r}")
        for name in (*_TERMS, "estimator_", "domain_calibration_"):
            self.__dict__.pop(name, None)
        if self.holdout is None:
            self._calibrate_fitted(X, y, wrench_delay_s)
        else:
            self._fit_held_out(X, y, groups, wrench_delay_s)
        return self

    def _calibrate_fitted(self, X, y, wrench_delay_s):
        if self.estimator is None:
            raise ValueError("DomainCalibratedHybrid(holdout=None) calibrates a fitted hybrid: "
                             "pass estimator=HybridCompensator(...).fit(X, y)")
        check_is_fitted(self.estimator)
        self.estimator_ = self.estimator
        X = np.asarray(X, dtype=float)
        Y = np.asarray(y, dtype=float).reshape(len(X), -1)
        before = coverage(Y, self.estimator_.predict(X), self.estimator_.predict_std(X))
        self._set_terms(self.estimator_.domain_terms(X, Y, shared_growth=self.shared_growth,
                                                     in_domain=self.in_domain))
        self.wrench_delay_s_ = (float(getattr(self.estimator_, "wrench_delay_s_", 0.0))
                                if wrench_delay_s is None else float(wrench_delay_s))
        self.domain_calibration_ = {
            "rows": len(X), **self._record(),
            "in_domain_std": np.sqrt(self.residual_noise_var_).tolist(),
            "parameter_variance_scale": float(self.domain_parameter_scale_),
            "coverage_95_before": before.tolist(),
            "coverage_95_after": coverage(Y, self.predict(X), self.predict_std(X)).tolist()}

    def _fit_held_out(self, X, y, groups, wrench_delay_s):
        X = np.asarray(X, dtype=float)
        Y = np.asarray(y, dtype=float).reshape(len(X), -1)
        base = self.estimator if self.estimator is not None else HybridCompensator()
        columns = X.shape[1] - X.shape[1] % 3  # [q, q̇, q̈]; a temperature column after them
        residual = base.get_params()["residual"]
        features = getattr(residual if residual is not None else default_residual(),
                           "features", "q")
        inputs = X[:, :check_feature_set(features) * (columns // 3)]
        held, chosen = domain.farthest_groups(inputs, groups, self.holdout)
        self.estimator_ = clone(base).fit(X[~held], Y[~held], wrench_delay_s=wrench_delay_s)
        before = coverage(Y[held], self.predict(X[held]), self.predict_std(X[held]))
        terms = self.estimator_.domain_terms(X[held], Y[held], shared_growth=self.shared_growth,
                                             in_domain=self.in_domain)
        self._set_terms(terms)
        record = {
            "held_out_groups": chosen, "held_out_rows": int(held.sum()),
            "training_rows": int((~held).sum()), **self._record(),
            "parameter_variance_scale": float(self.domain_parameter_scale_),
            "refit": bool(self.refit),
            "coverage_95_before": before.tolist(),
            "coverage_95_after": coverage(Y[held], self.predict(X[held]),
                                          self.predict_std(X[held])).tolist(),
            "median_distance_held_out": float(np.median(self.domain_distance(X[held]))),
        }
        if self.refit:
            self.estimator_ = clone(base).fit(X, Y, wrench_delay_s=wrench_delay_s)
            if self.in_domain == "held_out":  # else the refit's own cross-fit σ²_in
                self.residual_noise_var_ = self.estimator_._training_var() + terms["excess_var"]
            else:
                del self.residual_noise_var_, self.domain_excess_var_
        record["in_domain_std"] = np.sqrt(np.nan_to_num(self._noise_var())).tolist()
        self.wrench_delay_s_ = self.estimator_.wrench_delay_s_
        self.domain_calibration_ = record

    def _set_terms(self, terms: dict) -> None:
        self.domain_length_ = terms["length"]
        self.residual_noise_var_ = terms["in_var"]
        self.domain_growth_ = terms["growth"]
        self.domain_parameter_scale_ = terms["parameter_scale"]
        self.domain_excess_var_ = terms["excess_var"]

    def _record(self) -> dict:
        length = self.domain_length_
        return {"length": float(length) if np.isfinite(length) else None,  # None: ℓ = ∞
                "growth": self.domain_growth_.tolist(),
                "shared_growth": bool(self.shared_growth), "in_domain": self.in_domain}
