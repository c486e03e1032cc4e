r"""Analysis of a damped piston record (magnetic granular damper, thesis Sec. 5.3).

A free piston of given mass falls on the magnetic bed and oscillates with damping about a rest height.
This package analyses such a height record ``z(t)``; it is independent of the engine (pure functions on
arrays, results as small frozen dataclasses with ``.to_series()`` or as pandas DataFrames); only
:func:`sweep_metrics`, the adapter for ``pyorch.sweep``, and the command line read a run directory.
Every name below is importable from ``pyorch.bed.damper`` itself; each module holds one concern.

Units
-----
Times in ``T = sqrt(D1/g)``, heights in ``D1`` for a raw record ``H(t)`` (``piston.dat`` columns ``t`` and
``H``). Every function is unit-agnostic: frequencies come out in rad per time unit of ``t``, amplitudes in
the unit of ``z``. The Van der Pol-like model is meant for the *normalised* record of :func:`normalise`
(dimensionless height, time in ``t_scale`` units; :mod:`~pyorch.bed.damper.vdp` says why that map).

Contents
--------
:mod:`~pyorch.bed.damper.record`: the record and its extrema
    :func:`record_from_frame`, :func:`peaks`, :func:`log_decrement` (:class:`LogDecrement`)
:mod:`~pyorch.bed.damper.linear`: linear damped oscillator ``z'' + 2 zeta omega z' + omega^2 (z - z_eq) = 0``
    :func:`damped_cosine`, :func:`fit_linear_oscillator` (:class:`LinearOscillatorFit`)
:mod:`~pyorch.bed.damper.vdp`: Van der Pol-like model, thesis eq. (5.12) ``z'' + 2 a (z^2 - 2 z) z' + w^2 z = g0``
    :func:`normalise` (:class:`NormalisedRecord`), :func:`vdp_rhs`, :func:`simulate_vdp`,
    :func:`fit_vdp` (:class:`VdPFit`)
:mod:`~pyorch.bed.damper.selection`: model selection and sparse identification
    :func:`compare_models`, :func:`fit_sindy` (:class:`SindyModel`, needs the optional ``pysindy``)
:mod:`~pyorch.bed.damper.identify`: damper runs (the thesis' experiment; identification that refuses rather than invents)
    :func:`recorded_motion`, :func:`identify_fall` (eq. 5.12 as the thesis fitted it, with
    ``alpha = a``), :func:`identify_record`, :func:`sweep_metrics`
:mod:`~pyorch.bed.damper.plots`: figures
    :func:`plot_fit`, :func:`plot_phase`
:mod:`~pyorch.bed.damper.cli`: ``python -m pyorch.bed.damper RUN_DIR``
    :func:`main`
:mod:`~pyorch.bed.damper.fitstats`: goodness of fit and covariance shared by the fits
"""
from __future__ import annotations

from pyorch.bed.damper.cli import main
from pyorch.bed.damper.identify import (IDENTIFY_DEFAULTS, PHASE_FALL, PHASE_FREE, THESIS_VDP,
                                        identify_fall, identify_record, recorded_motion,
                                        sweep_metrics)
from pyorch.bed.damper.linear import (LINEAR_PARAMS, LinearOscillatorFit, damped_cosine,
                                      fit_linear_oscillator)
from pyorch.bed.damper.plots import plot_fit, plot_phase
from pyorch.bed.damper.record import LogDecrement, log_decrement, peaks, record_from_frame
from pyorch.bed.damper.selection import SindyModel, compare_models, fit_sindy
from pyorch.bed.damper.vdp import (VDP_PARAMS, NormalisedRecord, VdPFit, fit_vdp, normalise,
                                   simulate_vdp, vdp_rhs)

__all__ = [
    "NormalisedRecord",
    "LogDecrement",
    "LinearOscillatorFit",
    "VdPFit",
    "SindyModel",
    "record_from_frame",
    "normalise",
    "peaks",
    "log_decrement",
    "damped_cosine",
    "fit_linear_oscillator",
    "vdp_rhs",
    "simulate_vdp",
    "fit_vdp",
    "compare_models",
    "fit_sindy",
    "plot_fit",
    "plot_phase",
    "THESIS_VDP",
    "recorded_motion",
    "identify_fall",
    "identify_record",
    "sweep_metrics",
    "IDENTIFY_DEFAULTS",
    "PHASE_FALL",
    "PHASE_FREE",
    "LINEAR_PARAMS",
    "VDP_PARAMS",
    "main",
]
