"""Goodness of fit and covariance shared by the damper's model fits (linear oscillator, eq. 5.12).

``_r2`` (coefficient of determination), ``_aic`` (Akaike, Gaussian residuals), ``_covariance``
(``s^2 (J^T J)^-1``), ``_wrap`` (an angle to (-pi, pi]) and ``_FitMixin`` (parameter dicts, errors
and ``to_series`` of the frozen fit results).
"""
from __future__ import annotations

import math
from dataclasses import fields

import numpy as np
import pandas as pd
from numpy.typing import NDArray


def _r2(z: NDArray, model: NDArray) -> float:
    """Coefficient of determination 1 - RSS / TSS (NaN for constant z)."""
    tss = float(np.sum((z - z.mean()) ** 2))
    return 1.0 - float(np.sum((z - model) ** 2)) / tss if tss > 0 else float("nan")


def _aic(rss: float, n: int, p: int) -> float:
    """Akaike information criterion for Gaussian residuals, ``n log(RSS/n) + 2 p``."""
    return n * math.log(rss / n) + 2 * p if rss > 0 else -math.inf


def _covariance(jac: NDArray, rss: float, n: int) -> NDArray[np.float64]:
    """``sigma^2 (J^T J)^-1`` with ``sigma^2 = RSS / (n - p)`` (pseudo-inverse if singular)."""
    p = jac.shape[1]
    s2 = rss / (n - p) if n > p else float("nan")
    return np.linalg.pinv(jac.T @ jac) * s2


def _wrap(phi: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    w = math.remainder(phi, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


class _FitMixin:
    """Shared behaviour of the fit results: parameter dicts, evaluation, Series."""

    model: str
    _names: tuple[str, ...] = ()

    @property
    def params(self) -> dict[str, float]:
        """Fitted (or fixed) parameter values by name."""
        return {k: float(getattr(self, k)) for k in self._names}

    @property
    def errors(self) -> dict[str, float]:
        """1-sigma uncertainties by parameter name (NaN for a parameter held fixed)."""
        return {k: float(getattr(self, f"{k}_err")) for k in self._names}

    def to_series(self) -> pd.Series:
        """Scalar fields (parameters, ``*_err``, goodness of fit) as a float Series named after the model."""
        data = {f.name: getattr(self, f.name) for f in fields(self)  # type: ignore[arg-type]
                if f.name not in {"model", "free", "cov", "predict"}}
        return pd.Series(data, dtype=float, name=self.model)

