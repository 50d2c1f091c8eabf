"""Soil-parameter identification: bounded IPOPT fits, the seed's methods, uncertainty.

Public names
------------
:func:`fit`
    One dataset (tractive force-slip or drawbar pull-slip data, or a drive log) ->
    :class:`FitResult`; ``effects=[...]`` fits unmodelled effects jointly with the soil,
    ``fixed={"effect.param": value}`` holds some. The result's ``effects``, ``effect_set``,
    ``parameter_names``, ``jacobian``, ``weighted_residuals``, ``predict`` and ``residuals_on``
    (held-out data) serve the sim-to-real diagnosis.
:func:`fit_many`
    Many datasets (vectorised engine for same-size slip data, any ``Executor``).
:func:`profile_likelihood`
    Profile of the cost along one parameter and its likelihood-ratio interval.
:func:`build_result`
    Shared constructor of :class:`FitResult` for every method.
:class:`FitSettings`, :data:`ENGINES`, :data:`DEFAULT_ENGINE`
    Typed solver settings and the engine vocabulary (:mod:`soiltrack.identify.engines`).
:class:`FitResult`, :class:`ParameterEstimate`, :class:`Combination`, :class:`ProfileResult`,
:class:`FitFailed`.
:func:`diagnose`, :class:`Diagnosis`
    Sim-to-real gap diagnosis: where the gap lies, which unmodelled effect explains it.
:class:`OnlineEstimator`, :class:`OnlineSettings`, :class:`OnlineEstimate`
    On-line identification while driving, with change-of-terrain detection.
:func:`fit_soil_test`, :class:`Estimate` (``SoilTestFit``), :func:`predict_drawbar_pull`
    Bevameter shear and plate sinkage tests (:mod:`soiltrack.identify.soiltests`), and a
    track's drawbar pull predicted from them. :class:`Estimate` is the one record every kind moves onto
    (:mod:`soiltrack.identify.estimates.estimate`).
:func:`fit_sinkage_channel`, :class:`SinkageChannelFit`, :func:`slip_sinkage_evidence`, :class:`SlipSinkageEvidence`
    A track sweep's measured sinkage (``sinkage_m``) against the Bekker and slip-sinkage laws
    (:mod:`soiltrack.identify.sweep.sinkage_channel`): n, k_c / b + k_phi, the slip exponent,
    and the evidence of slip sinkage that the diagnosis weighs.
"""

from . import jitcache  # noqa: F401 - soiltrack.identify.jitcache, the compiled-code cache
from .batch import fit_many
from .engines import DEFAULT_ENGINE, ENGINES
from .diagnosis.diagnose import Diagnosis, diagnose
from .fitting import fit
from .sweep.problem import FitFailed
from .sweep.likelihood import ProfileResult, profile_likelihood
from .estimates.result import Combination, FitResult, ParameterEstimate, build_result
from .settings import FitSettings
from .online import OnlineEstimate, OnlineEstimator, OnlineSettings
from .estimates.estimate import Estimate
from .soiltests import SoilTestFit, fit_soil_test, predict_drawbar_pull
from .sweep.sinkage_channel import SinkageChannelFit, SlipSinkageEvidence, fit_sinkage_channel, slip_sinkage_evidence

__all__ = [
    "fit",
    "fit_many",
    "profile_likelihood",
    "build_result",
    "FitResult",
    "ParameterEstimate",
    "Combination",
    "ProfileResult",
    "FitFailed",
    "FitSettings",
    "ENGINES",
    "DEFAULT_ENGINE",
    "diagnose",
    "Diagnosis",
    "fit_soil_test",
    "SoilTestFit",
    "Estimate",
    "predict_drawbar_pull",
    "OnlineEstimator",
    "OnlineSettings",
    "OnlineEstimate",
    "fit_sinkage_channel",
    "SinkageChannelFit",
    "slip_sinkage_evidence",
    "SlipSinkageEvidence",
]
