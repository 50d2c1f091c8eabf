"""Typed settings of the on-line estimator (:class:`OnlineSettings`): every decision threshold named."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ...soilmodel.effects import EFFECTS
from ...soilmodel.errors import DataError
from ...soilmodel.soil import PRACTICAL_BOUNDS, SoilBounds
from ...soilmodel.tracks import TURN_THRESHOLD_SIGMA
from ...soilmodel.traction import check_model

__all__ = ["OnlineSettings"]

#: Admissible grade, rad: the ``grade`` effect's range (soilmodel's registry).
_GRADE_RANGE = (EFFECTS["grade"].params[0].lower, EFFECTS["grade"].params[0].upper)


@dataclass(frozen=True)
class OnlineSettings:
    """Settings of :class:`~.estimator.OnlineEstimator` (SI units).

    Attributes
    ----------
    window_s
        Length of the moving horizon, s: the estimate rests on the samples of the last
        ``window_s`` seconds (and on none before the last detected change of terrain).
    grade_rad
        Known grade of the ground the vehicle drives on, rad, positive uphill (0: flat). The
        normal load becomes ``W cos(theta)`` (:func:`soiltrack.soilmodel.effects.effective_normal_load`):
        the estimate's F_max is the limit at that load and its bounds are those of
        ``A c + W cos(theta) tan(phi)`` over the soil box. The grade's ``W sin(theta)`` acts on the
        hull, which neither residual of the estimator (track speed, sprocket thrust) contains:
        the fitted F_max and K do not depend on it (see docs/online.md, "On a slope").
        Within the ``grade`` effect's range (+-1.2 rad).
    model, bounds
        Thrust law (``"full"`` or ``"cohesion-free"``) and the soil box; F_max is bounded by
        the range of ``A c + W tan(phi)`` over the box, K by its K range.
    sigma_torque, sigma_sprocket_speed, sigma_vehicle_speed
        Sensor noise standard deviations (N m, rad/s, m/s), or ``None``: estimated from the
        window's own readings, as the batch fit does.
    noise_every
        Updates between two re-estimates of the noise levels from the window.
    min_speed
        Samples slower than this (m/s, vehicle or track) are not used (the batch fit's option).
    max_step_ratio
        A time step longer than this many times the running median step breaks the sample
        chain (the sprocket equation over a long gap would assume the torque held all along).
    max_steps_per_update, converged_decrement
        Gauss-Newton steps per update while not converged (one when converged), and the
        convergence test: the squared Newton decrement (the step's size in standard errors,
        squared) below this value.
    hold_rel
        Once the horizon has determined F_max, a weak prior (standard deviation ``hold_rel``
        times that F_max) holds it there while later horizons do not (gentle driving shows only
        the slope, along which F_max would drift to a bound). Against data that determine F_max
        to a few percent it moves the estimate by well under a tenth of a standard error; it
        is dropped when a change of terrain is detected.
    max_step_scaled
        Largest change of F_max or K per Gauss-Newton step, relative to its current value (a
        trust region for steps along the poorly determined direction of gentle driving).
    detect_reference, detect_threshold, detect_clip
        Two-sided CUSUM of the standardised one-step prediction residuals of new samples: drift
        ``k`` (half the smallest shift it is meant to catch, in standard deviations), alarm
        threshold ``h`` and the clip of each residual (one wild sample cannot raise an alarm
        alone). With k = 1, h = 10 the average run length between false alarms of white
        Gaussian residuals is far beyond 10^8 samples.
    identify_min_utilisation
        F_max (and K) count as identified only when the horizon's largest thrust (two standard
        deviations below its value) reaches this fraction of the estimate, besides the batch
        fit's rules (correlation below 0.99, standard error below 25 %, not on a bound): gentle
        driving shows only the start of the curve, and a covariance computed where the
        iterate has drifted along the ridge can look tighter than the data are.
    identify_min_informative
        A horizon that identifies F_max is fused into the held estimate (and tested against it)
        only when it holds at least this many informative samples (loaded to
        ``identify_min_utilisation`` of F_max): the sandwich covariance estimates the scores'
        variance from the samples themselves, and two or three samples of a short pull give no
        estimate of it (measured: a horizon holding the last three samples of a pull on the light
        vehicle reported F_max to 2 % and was contradicted by the next pull; at 5 the library's
        default profile's hard accelerations, light vehicle, were never fused).
    identify_min_samples
        F_max counts as identified only from a horizon holding at least this many used samples:
        its sandwich covariance and the noise levels are estimated from the horizon's own samples,
        and a handful of them give no estimate of either (measured: the first 0.5 s of a start-up
        acceleration, heavy vehicle at 25 Hz, 8 samples loaded to 18 % of the true F_max, reported
        F_max 37 +- 4.8 kN against 202 kN; held, that wrong value was never corrected). While
        nothing is held, the iteration must also have converged at that update (the first
        estimate of a soil has no arrival cost to be checked against, and an iterate between two
        Gauss-Newton steps is not a fit: measured, 58 +- 7 kN held from such an iterate, same
        vehicle). Once something is held the rule is the sample count only: a pull moves the
        iterate, and asking for convergence there missed a change (measured, heavy flat, pulls
        every 20-30 s: detected 48 s late instead of 0.5 s after the first pull on the new soil).
    identify_reject_factor, identify_reject_chi2
        The first estimate of a soil (nothing held: since the start or the last change) counts F_max
        as identified only when the horizon's data reject ``identify_reject_factor`` times its F_max,
        K refitted: twice the rise of the profiled cost, in noise variances, beyond
        ``identify_reject_chi2`` (a likelihood ratio; 9 = three standard deviations for one
        parameter). The other rules measure the horizon against its own estimate, which an
        underestimate along the F_max-K ridge passes (measured: a converged horizon of 31 gentle
        samples, heavy vehicle, its peak thrust 74 % of its own F_max, held 56.4 +- 12.2 kN against
        202.1 kN, z -11.9). Once something is held, the arrival cost checks a new horizon.
    detect_min_load
        The detector runs once F_max has been determined (since the start or the last change)
        and takes only samples whose thrust is at least this fraction of that F_max. Below it
        the thrust-slip curve is its initial slope, where a change of terrain hides in the slip
        noise (measured: no lean at all on the light vehicle at 2 m/s) while
        the slope's error-in-variables bias moves with the driving and would read as a change.
    detect_settle_s
        ... and only this long after F_max was first determined (since the start or the last
        change): the first pull's own samples refine the first estimate, and would otherwise
        read as a change.
    detect_scale_samples
        Recent prediction residuals whose robust spread (median absolute deviation, at least
        1) scales the detector's input.
    detect_min_samples, detect_min_s
        The detector runs only once the estimate rests on this many samples and this many
        seconds since the start or the last change.
    drift_max_thrust_rel, drift_shear_modulus_rel
        Random-walk rates of the held estimate (:mod:`~.memory`), per sqrt(s): between
        excitations F_max and K keep their last identified values and their variances grow by
        ``(rate x value)^2`` per second. 0.003 says the soil under a moving vehicle may drift by
        about 0.3 % in a second, 3 % in 100 s, 18 % in an hour (firm uniform ground; a patchy
        field wants more): small against the 20-40 % of a change of terrain, large enough that a
        value held for minutes is not trusted to the tenth of a percent a pull gave it.
    relaxation
        ``True`` (default): each sample's thrust is taken under the batch fit's slip-relaxation rule
        (``discretisation="relaxation"`` of :func:`~soiltrack.identify.drivelog.fit.fit_drive_log`) once
        its next sample has arrived: the interval's mean thrust lags the thrust at its end slip by
        up to half the change over the interval where the slip relaxes slowly against the sample
        step (light vehicle, short pulls), and the end-point rule then reads F_max a few percent
        high; a horizon fused into the memory would keep that bias. ``False``: the end-point rule.
    gentle_solve_every
        With the memory on, while the horizon holds no sample loaded to ``detect_min_load`` of the
        held F_max (gentle driving: the held estimate is reported, the horizon's own fit gives the
        slope only), its converged iteration is solved every this many samples instead of at each
        (the update time is mostly that solve; 1: at every sample). The detector still tests every
        new sample; the iterate it predicts with is then up to that many samples old.
    memory
        ``True`` (default): the held estimate of :mod:`~.memory` (arrival cost, random walk) is
        what each update reports and what the detector tests new samples against. ``False``: the
        window estimator of before (issue 22: the horizon's fit alone, forgotten as its samples
        leave; the detector against the horizon's iterate), kept for comparison.
    detect_held_sigmas
        The detector's residuals are standardised by the noise and by this many standard
        deviations of the prediction that the held estimate's own uncertainty allows: a change
        must move the thrust-slip curve beyond that many standard errors of what is known
        (the held estimate is shared by every sample, so its error would otherwise lean all of
        a pull's residuals to one side and read as a change).
    detect_window_chi2
        A second test: when the horizon identifies F_max, its own estimate against the arrival
        cost (what the samples before it said, grown by the random walk); a squared Mahalanobis
        distance beyond this (chi-square, 2 degrees of freedom; 27.6 = p 1e-6) is a change.
        A horizon beyond it is never fused into the held estimate.
    detect_window_min_load
        ... and a horizon is tested against the held estimate only when it holds
        ``identify_min_informative`` used samples loaded to this fraction of its own F_max (its
        plateau); a horizon below it is fused only when it agrees (distance within
        ``detect_window_chi2``) and never declares a change. Below it the horizon sees a pull's
        ramp only, and its F_max is an extrapolation along the ridge (correlation 0.95-0.99) that
        the sandwich covariance does not describe (measured: every false alarm of a 10-minute
        uniform heavy log came from horizons with 9-15 samples at 50-80 % of F_max and none above
        80 %). The first horizon still starts the held estimate.
    detect_window_plateau_samples
        ... and the threshold ``detect_window_chi2`` holds for a horizon with at least this many used samples
        on its plateau (loaded to ``detect_window_min_load`` of its own F_max); with ``n`` fewer (but at
        least one) it is ``detect_window_chi2 x detect_window_plateau_samples / n``. The sandwich
        covariance's score variance rests on those few samples: a pull's first samples on its plateau,
        while the slip still relaxes, give a horizon whose F_max is pulled along the ridge with a
        covariance that understates it (measured on the tuning set of ``bench_online.py --set``, heavy
        flat, pulls every 4-6 s: d2 45.8 and 35.0 from 3 and 4 plateau samples 0.4 s into a pull, F_max
        179 +- 6 kN against a held 205 +- 2 kN, truth 202 kN), while a change gives d2 of 80-300 from as
        few samples (a K x2 change's ramp included, whose F_max is lowered and that reaches the plateau
        of its own F_max only). Replaces the fixed rule "tested only from ``identify_min_informative``
        plateau samples" (a horizon below it is still fused only when it agrees).
    detect_excitation_chi2
        A third test, on each excitation (a run of samples loaded to ``detect_min_load`` of F_max, gaps
        below ``EXCITATION_GAP_S``) while something is held: the excitation's samples against the estimate
        held when it began, a score test (:class:`~.detector.ExcitationTest`: each sample's profiled
        residual there and its gradient in (F_max, K), the held covariance grown by the random walk); a
        statistic beyond this (chi-square, 2 degrees of freedom) is a change. It needs no fit of the new
        samples: the horizon test waits until a horizon identifies F_max, which a pull's ramp on a new
        soil does not (measured, tuning set of ``bench_online.py --set tuning``, heavy flat, pulls every
        25-35 s, F_max down 21 %: the horizon test flagged the first pull on the new soil 1.68 s after its
        first informative sample, this test 0.82-0.88 s). 36.8 is p = 1e-8 for one test: the test is
        repeated at each sample and over the candidate splits, and at p = 1e-6 (27.6) the tuning set's
        uniform hour had 1 false alarm (light, 10 deg, 502.8 s), at 36.8 none, at the cost of 2 of the 24
        F_max changes flagged later than 1 s (23 -> 21 of 24; ``bench_online.py --set tuning --setting
        detect_excitation_chi2=27.6``; see docs/online.md).
    detect_excitation_bias
        ... with a model error shared by an excitation's samples of this many noise standard deviations
        (:class:`~.detector.ExcitationTest`: ``n`` samples' noise part inflated by ``1 + n b^2``): a long run
        at one operating point (a steady climb) tests the mean of its residuals there, and a lean of the
        model of a fraction of the noise (the slope's error-in-variables bias, the controller's correlated
        noise) adds up over hundreds of samples (measured, tuning set, heavy 10 deg, steady climb at 37 %
        of F_max, no pull, horizon and held estimate agreeing (d2 < 1): with 0 a split statistic of 28.2
        and a false alarm at 61.18 s). 0.2 made the heavy flat F_max-down change above 1.68 s late again.
    detect_excitation_max_s
        ... and an excitation longer than this, s, is tested in parts of this length (each against the
        estimate held when it began): on continuous load (a climb loads every sample) one run would hold
        minutes of samples, its reference minutes old and its search for a change inside it (candidate
        splits every ``SPLIT_STRIDE`` samples) growing with it. Measured on the tuning set's in-pull change
        on 10 deg (seed 3016): the whole run's statistic 2 after 3000 samples of the climb (the change's
        lean diluted), the split search in 5-s parts flags it 0.34 s after the first sample on the new soil.
    detect_date_margin
        The excitation test dates a change at its most likely first sample on the new soil (the split of
        the excitation's samples with the largest statistic of the samples after it), and its window
        holds the splits whose statistic is within this margin of the largest (a likelihood interval),
        reaching back to the last informative sample before the excitation of its first split (on a climb
        the samples before a pull are loaded and show little: measured, light vehicle on 10 deg, a change
        between two pulls whose window started 5 s after it at a split inside the next pull).
        The statistic is linearised at the reference and the best split is chosen by it, so the
        interval is wider than a chi-square quantile: measured on the tuning set's in-pull change (heavy
        10 deg, seed 3016) the true first sample on the new soil was 14.6 below the best split (9, the
        chi-square(1) 99.7 % point, excluded it). The horizon restarts at the window's first split.
    detect_min_excitations
        A horizon that contradicts its arrival cost declares a change only when the arrival cost
        rests on at least this many excitations (runs of informative samples more than
        ``EXCITATION_GAP_S`` apart) since the start or the last change; otherwise the held
        estimate starts again from the horizon. One excitation (one pull) shows one operating
        point of the curve: its F_max is an extrapolation along the F_max-K ridge that the
        sandwich covariance understates (measured: a first pull of the heavy vehicle on 10 deg
        held 154 +- 8 kN, the next pull's horizon 228 +- 9 kN, truth 199 kN). The price: a
        change between the first and the second excitation is learnt, not flagged.
    turn_threshold
        Noise standard deviations of the left-right speed difference (or the yaw rate) beyond
        which a two-track sample turns.
    turn_history
        Samples of the speed difference (and yaw rate) the turning noise is estimated from.
    max_capacity
        Most samples in the horizon (the kernel is built for the capacity, grown by doubling).
    """

    window_s: float = 5.0
    grade_rad: float = 0.0
    model: str = "full"
    bounds: SoilBounds = PRACTICAL_BOUNDS
    sigma_torque: float | None = None
    sigma_sprocket_speed: float | None = None
    sigma_vehicle_speed: float | None = None
    noise_every: int = 200
    min_speed: float = 0.0
    max_step_ratio: float = 3.0
    max_steps_per_update: int = 4
    converged_decrement: float = 0.01
    max_step_scaled: float = 0.25
    hold_rel: float = 0.1
    detect_reference: float = 1.0
    detect_threshold: float = 10.0
    detect_clip: float = 4.0
    identify_min_utilisation: float = 0.5
    identify_min_informative: int = 4
    identify_min_samples: int = 20
    identify_reject_factor: float = 2.0
    identify_reject_chi2: float = 9.0
    detect_min_load: float = 0.2
    detect_settle_s: float = 2.0
    detect_scale_samples: int = 100
    detect_min_samples: int = 20
    detect_min_s: float = 0.5
    memory: bool = True
    relaxation: bool = True
    gentle_solve_every: int = 10
    drift_max_thrust_rel: float = 0.003
    drift_shear_modulus_rel: float = 0.003
    detect_held_sigmas: float = 4.0
    detect_window_chi2: float = 27.6
    detect_window_min_load: float = 0.8
    detect_window_plateau_samples: int = 8
    detect_excitation_chi2: float = 36.8
    detect_excitation_bias: float = 0.1
    detect_excitation_max_s: float = 5.0
    detect_date_margin: float = 20.0
    detect_min_excitations: int = 2
    turn_threshold: float = TURN_THRESHOLD_SIGMA
    turn_history: int = 256
    max_capacity: int = 16384

    def __post_init__(self) -> None:
        check_model(self.model)
        for name in (
            "window_s",
            "max_step_ratio",
            "converged_decrement",
            "max_step_scaled",
            "hold_rel",
            "identify_min_utilisation",
            "detect_min_load",
            "detect_reference",
            "detect_threshold",
            "detect_clip",
            "turn_threshold",
            "detect_window_chi2",
            "detect_window_min_load",
            "identify_reject_chi2",
            "detect_excitation_chi2",
            "detect_date_margin",
            "detect_excitation_max_s",
        ):
            val = getattr(self, name)
            if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val) or val <= 0:
                raise DataError(f"setting {name} must be a finite number > 0, got {val!r}")
        for name in (
            "noise_every",
            "max_steps_per_update",
            "detect_scale_samples",
            "detect_min_samples",
            "identify_min_informative",
            "identify_min_samples",
            "detect_min_excitations",
            "detect_window_plateau_samples",
            "gentle_solve_every",
            "turn_history",
            "max_capacity",
        ):
            val = getattr(self, name)
            if isinstance(val, bool) or not isinstance(val, int) or val < 1:
                raise DataError(f"setting {name} must be an integer >= 1, got {val!r}")
        for name in (
            "sigma_torque",
            "sigma_sprocket_speed",
            "sigma_vehicle_speed",
            "min_speed",
            "detect_min_s",
            "detect_settle_s",
            "drift_max_thrust_rel",
            "drift_shear_modulus_rel",
            "detect_held_sigmas",
            "detect_excitation_bias",
        ):
            val = getattr(self, name)
            if val is not None and (
                isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val) or val < 0
            ):
                raise DataError(f"setting {name} must be a finite number >= 0, got {val!r}")
        for name in ("memory", "relaxation"):
            if not isinstance(getattr(self, name), bool):
                raise DataError(f"setting {name} must be True or False, got {getattr(self, name)!r}")
        g = self.grade_rad
        lo, hi = _GRADE_RANGE
        if isinstance(g, bool) or not isinstance(g, (int, float)) or not math.isfinite(g) or not lo <= g <= hi:
            raise DataError(f"setting grade_rad must be a finite number in [{lo:g}, {hi:g}] rad, got {g!r}")
        f = self.identify_reject_factor
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f) or f <= 1:
            raise DataError(f"setting identify_reject_factor must be a finite number > 1, got {f!r}")
        if self.max_step_ratio <= 1:
            raise DataError(f"setting max_step_ratio must be > 1, got {self.max_step_ratio!r}")
