"""Every threshold, level and count of the diagnosis, each with the reason for its value.

:class:`DiagnoseSettings` is the one place the decision code takes a number from; ``diagnose(...,
settings=DiagnoseSettings(alpha=0.05))`` changes one of them for a run.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DiagnoseSettings", "DEFAULT_SETTINGS"]


@dataclass(frozen=True)
class DiagnoseSettings:
    """Thresholds, levels and counts of :func:`~.diagnose.diagnose` (frozen; one reason per field).

    Attributes
    ----------
    alpha
        Significance level of every test the decision uses (the gap tests, a cause's own test):
        1 %, so that one diagnosis in a hundred of effect-free data sees a gap by chance.
    min_explained
        Least share of the nominal model's excess error over the noise that the heaviest hypothesis
        must remove to be the verdict: below half, something else carries most of the gap.
    min_shrink
        Least held-out RMS shrink (with a significant Diebold-Mariano test) that shows a gap when the
        nominal error alone is within the noise: 5 % is about what a half-size effect gives on a
        one-minute log, and more than chance gains of hundreds of held-out samples.
    min_samples
        Fewest samples for a blocked hold-out: two folds of alternate blocks of at least 2 samples.
    sweep_blocks
        Contiguous blocks of a sweep's hold-out, in slip: 10, so that a block holds a few readings.
    log_blocks
        Contiguous blocks of a drive log's hold-out, in time: 30 (2 s on a one-minute run) puts
        training samples inside any window of a few seconds (a change of terrain is judged on its
        own held-out samples) and breaks the alignment of blocks with a driving profile's bursts of
        pushing, while staying long against the residuals' correlation time (a few samples).
    sweep_folds
        Folds of a sweep's hold-out (each block held out once): every fit sees four fifths of it.
    log_refits
        Library effects refitted on a drive log (the strongest by score gain): each costs a fit of
        a few hundred milliseconds; the score gain ranks the true effect in the first three on the
        simulated grid.
    log_outside_refits
        Library effects outside the user's candidates refitted on a drive log (by score gain): the
        two most likely imitators of the left-out truth.
    warm_max_iter
        IPOPT iterations of a warm-started drive-log fit (from the full-data answer): a hypothesis
        close to the nominal soil converges in a few dozen; more is a wandering search.
    retry_max_iter
        IPOPT iterations of a sweep fit with an effect retried after a stall: strain-softening fits
        meet the default 500 in a slow valley.
    log_knots_per_sample, log_min_knots, log_max_knots
        Knots of the flexible term in time on a log: one per 150 samples, 8 to 20 (a smooth trend,
        not the noise).
    sweep_samples_per_knot, sweep_min_knots, sweep_max_knots
        Knots of the flexible term in slip on a sweep: one per 6 samples, 2 to 12.
    confusable_ratio, confusable_corr, confusable_weight
        Two library hypotheses are confusable when the smaller weight is at least this share of the
        larger (and at least ``confusable_weight``) and their sensitivities are this collinear (the
        flexible term: with any effect of close weight); a confusable group shares its weight. A
        factor 5 of weight is 1.6 in held-out log density; a grade and a drivetrain loss that
        predict a simulated log alike (held-out shrinks 0.4053 and 0.4051) reach 0.76 and 0.24 (1.2).
    confusable_separation
        Two collinear hypotheses whose difference of evidence is within this many of its standard
        errors are confusable too, whatever their weights (the larger at least ``confusable_weight``):
        2, a two-sided 5 % level. A pseudo-BMA+ weight is about the bootstrap's probability that one
        predicts better: 0.98 for a speed-sensor scale 1.8 standard errors ahead of a radius error (the
        grid's light log, doubled noise, dry sand, seed 1, before the evidence weighed a log's channels
        by the sensors' noise), beyond the factor 5 of ``confusable_ratio`` though not a difference a
        5 % test shows.
    max_delay_samples
        Largest delay between channels tried (samples): a quarter second at 100 Hz.
    sweep_noise_window
        Share of a sweep's rows in the moving window of its noise profile: a quarter, so that the
        profile follows the noise's shape along the slip (larger at small slip, where slip noise meets
        a steep curve) without the row-to-row wiggles of a few squared differences, which would give
        the rows random weights and a lack-of-fit test that finds structure in them.
    terrain_grid, terrain_slope_ratio, terrain_refine_steps, terrain_tol_log_k
        The small-slip slope inside a terrain window (carried by K, the thrust limit kept) is searched
        on a grid of this many points in log K, within ``terrain_slope_ratio`` (100) times the outside
        soil's either way (a slope beyond a hundredfold change is no soil but a fault): 9 points, a
        factor 3.2 apart; then refined inside the grid's bracket by parabolic steps (at most 6) until
        a step moves log K by less than 0.01 (K within 1 %, finer than a window's data tell).
    n_bootstrap
        Bayesian-bootstrap replicates of the pseudo-BMA+ weights: 400 keeps their Monte Carlo error
        below 0.01.
    """

    alpha: float = 0.01
    min_explained: float = 0.5
    min_shrink: float = 0.05
    min_samples: int = 8
    sweep_blocks: int = 10
    log_blocks: int = 30
    sweep_folds: int = 5
    log_refits: int = 3
    log_outside_refits: int = 2
    warm_max_iter: int = 60
    retry_max_iter: int = 3000
    log_knots_per_sample: int = 150
    log_min_knots: int = 8
    log_max_knots: int = 20
    sweep_samples_per_knot: int = 6
    sweep_min_knots: int = 2
    sweep_max_knots: int = 12
    confusable_ratio: float = 0.2
    confusable_corr: float = 0.9
    confusable_weight: float = 0.05
    confusable_separation: float = 2.0
    max_delay_samples: int = 25
    sweep_noise_window: float = 0.25
    terrain_grid: int = 9
    terrain_refine_steps: int = 6
    terrain_tol_log_k: float = 0.01
    terrain_slope_ratio: float = 100.0
    n_bootstrap: int = 400

    def noise_window(self, n: int, is_log: bool) -> int | None:
        """Moving window of the noise profile of ``n`` samples (None on a log: the profile's default)."""
        return None if is_log else max(7, int(round(self.sweep_noise_window * n)))

    def knots(self, n: int, is_log: bool) -> int:
        """Knots of the flexible term for ``n`` samples of a log or a sweep."""
        if is_log:
            return int(min(self.log_max_knots, max(self.log_min_knots, n // self.log_knots_per_sample)))
        return int(max(self.sweep_min_knots, min(self.sweep_max_knots, n // self.sweep_samples_per_knot)))


#: The settings :func:`~.diagnose.diagnose` uses when none are given.
DEFAULT_SETTINGS = DiagnoseSettings()
