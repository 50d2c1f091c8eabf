"""Drive logs: the soil from a straight-line run (sprocket torque, sprocket speed, vehicle speed).

Modules: :mod:`.prepare` (checks, noise, sample selection), :mod:`.noise` (sensor noise from the
log), :mod:`.nlp` (output-error NLP with latent slips), :mod:`.fit` (``fit_drive_log``),
:mod:`.joint` / :mod:`.joint_fit` (with unmodelled effects), :mod:`.lm_start` (a start near the
optimum), :mod:`.covariance` (sandwich covariance), :mod:`.regime` (gentle or hard driving),
:mod:`.relaxation` (the held-torque discretisation's weights),
:mod:`.residuals` / :mod:`.sensitivity` (per-sample residuals and sensitivities), :mod:`.simex`
(opt-in bias correction), :mod:`.torque_hold` (a torque hold the user did not state).
"""

from .fit import DriveLogFitError, fit_drive_log
from .regime import classify_regime
from .relaxation import DISCRETISATIONS
from .residuals import DriveLogResiduals, drive_log_residuals
from .sensitivity import DriveLogSensitivities, drive_log_sensitivities

__all__ = [
    "DISCRETISATIONS",
    "fit_drive_log",
    "DriveLogFitError",
    "classify_regime",
    "DriveLogResiduals",
    "drive_log_residuals",
    "DriveLogSensitivities",
    "drive_log_sensitivities",
]
