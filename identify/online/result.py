"""What one update of the on-line estimator gives: :class:`OnlineEstimate` (frozen, SI)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["OnlineEstimate", "IDENTIFIABLE_NAMES", "NOT_SEPARABLE"]

#: The quantities an estimate can call identified: the small-slip slope ``F_max l / (2 K)``
#: (gentle driving), and F_max and K themselves (a pull near the traction limit).
IDENTIFIABLE_NAMES = ("slope", "max_thrust", "shear_modulus")
#: Never identified on-line: the horizon holds one normal load, and at one load c and phi enter
#: the thrust only through F_max = A c + N tan(phi) (their Jacobian columns are proportional), so
#: any (c, phi) on that line fits the same. Separating them needs loads that differ (a payload,
#: a change of grade, a rig sweep at several loads: the batch ``fit`` of such data).
NOT_SEPARABLE = ("cohesion", "friction_angle")


@dataclass(frozen=True, eq=False)
class OnlineEstimate:
    """The estimate after one update of :class:`~.estimator.OnlineEstimator`.

    Attributes
    ----------
    time_s
        Time of the sample just processed, s.
    max_thrust_N, shear_modulus_m
        Current estimate of the thrust limit F_max = A c + N tan(phi) at the normal load N
        (``normal_load_N``), N, and of K (m); the
        values of the moving-horizon fit even when they are not identifiable (then only their
        slope is: see ``identifiable``). ``None`` before the first estimate.
    max_thrust_stderr_N, shear_modulus_stderr_m
        Standard errors: of the held estimate (the horizon's sandwich covariance fused with the
        arrival cost, grown by the random walk between excitations), ``None`` while the quantity
        is not identifiable.
    covariance
        2x2 covariance over ``[max_thrust_N, shear_modulus_m]`` (SI). Once something is held
        (``OnlineSettings.memory``): the held estimate's, given whenever F_max is identified (K's
        variance in it may then be beyond K's 25 % rule: K is not called identified). Before, and
        with ``memory=False``: the horizon's, ``None`` unless F_max and K are both identifiable.
    slope_N, slope_stderr_N
        The small-slip slope ``F_max l / (2 K)`` (thrust per unit slip) and its standard error
        (``None`` before an estimate exists).
    normal_load_N
        Normal load N of the estimate, N: ``W cos(theta)`` on the known grade theta
        (``grade_rad``, :func:`soiltrack.soilmodel.effects.effective_normal_load`), the vehicle's
        weight W on flat ground. F_max is the limit at this load.
    grade_rad
        The known grade the estimate assumes (``OnlineSettings.grade_rad``), rad, positive uphill.
    identifiable
        What the horizon's data pin down now: ``()`` (too few samples), ``("slope",)`` (gentle
        driving), ``("slope", "max_thrust")`` or ``("slope", "max_thrust", "shear_modulus")``.
        Never ``cohesion`` or ``friction_angle``: see ``not_identifiable``.
    not_identifiable
        What the estimate does not identify: the names of :data:`IDENTIFIABLE_NAMES` missing from
        ``identifiable``, and always :data:`NOT_SEPARABLE` (``"cohesion"``, ``"friction_angle"``:
        one normal load, only their combination F_max is determined).
    slip
        The latent (true) slip of the sample just processed, ``None`` when it was not used.
    change_detected
        ``True`` on the update that detected a change of terrain.
    change_time_s
        Estimated start of the detected change (the time the detector's statistic last left
        zero), ``None`` unless ``change_detected``.
    samples_used
        Samples the current estimate rests on (inside the horizon, after the sample selection).
    samples_skipped
        Samples skipped so far because a channel was missing or not finite.
    samples_turning
        Two-track samples left out so far because the vehicle turned.
    samples_seen
        Samples given to the estimator so far.
    converged
        Whether the Gauss-Newton iteration has converged on the horizon's fit (squared Newton
        decrement below the setting).
    status, message
        ``"ok"``, ``"warming_up"`` (no estimate yet), ``"not_converged"``, ``"skipped"``
        (this sample skipped), and a sentence saying why.
    detector
        The change detector's statistic after this update (CUSUM, in standard deviations).
    informed_at_s
        Time of the last sample that carried information on F_max (a used sample whose thrust,
        two standard deviations below its value, reaches ``identify_min_utilisation`` of F_max)
        since the start or the last change of terrain; ``None`` before the first.
    change_window_s
        On the update that detects a change: ``(earliest, latest)``, the times between which it
        can have happened (the last informative sample on the old soil, the first on the new);
        ``None`` otherwise.
    held
        ``True`` when the values are the held estimate carried from earlier samples (no
        informative sample in the horizon: its covariance grown by the random walk).
    """

    time_s: float
    max_thrust_N: float | None
    max_thrust_stderr_N: float | None
    shear_modulus_m: float | None
    shear_modulus_stderr_m: float | None
    covariance: np.ndarray | None
    slope_N: float | None
    slope_stderr_N: float | None
    normal_load_N: float
    grade_rad: float
    identifiable: tuple[str, ...]
    not_identifiable: tuple[str, ...]
    slip: float | None
    change_detected: bool
    change_time_s: float | None
    samples_used: int
    samples_skipped: int
    samples_turning: int
    samples_seen: int
    converged: bool
    status: str
    message: str
    detector: float
    informed_at_s: float | None = None
    change_window_s: tuple[float, float] | None = None
    held: bool = False

    @classmethod
    def from_fields(cls, fields: dict) -> OnlineEstimate:
        """Build from a dict holding every field (the estimator's per-update fast path).

        The frozen ``__init__`` sets its fields one ``object.__setattr__`` at a time, at every
        update; this fills the instance's dict at once. A missing or unknown field is refused,
        as ``__init__`` would refuse it.
        """
        if fields.keys() != _FIELDS:
            raise TypeError(f"OnlineEstimate fields differ: {sorted(fields.keys() ^ _FIELDS)}")
        obj = cls.__new__(cls)
        obj.__dict__.update(fields)
        return obj

    def as_dict(self) -> dict:
        """JSON-ready dict (``covariance`` as a nested list or ``None``; ``identifiable`` a list)."""
        out = {k: getattr(self, k) for k in self.__dataclass_fields__}
        out["identifiable"] = list(self.identifiable)
        out["not_identifiable"] = list(self.not_identifiable)
        out["covariance"] = None if self.covariance is None else np.asarray(self.covariance).tolist()
        out["change_window_s"] = None if self.change_window_s is None else list(self.change_window_s)
        return out


_FIELDS = frozenset(OnlineEstimate.__dataclass_fields__)
