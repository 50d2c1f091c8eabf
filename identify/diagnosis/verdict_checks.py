"""Last checks on a verdict that names an effect: is there a gap, and does the effect explain it?

The weights of :mod:`.selection` compare models with each other; with hundreds of held-out
samples they become decisive over differences too small to matter (two candidates that each
shave 0.1 % off the held-out error of an effect-free log can carry weights of 0.5 and 0.4), and
a candidate that imitates an effect outside the library a little better than the others carries
the whole weight. Two checks against the noise floor, not against the other models, guard the
name:

- **Is there a gap?** When the nominal model's held-out error is not significantly above the
  noise floor (:func:`~.selection.gap_p_value`) and the named effect does not predict the held-out
  data both significantly (Diebold-Mariano, :func:`~.selection.dm_test`) and appreciably
  (held-out RMS down by at least ``MIN_SHRINK``) better than the nominal model, there is nothing
  to explain: the verdict is ``none``. (On an effect-free log of 1,200 samples, a candidate that
  shaves 0.5 % off the held-out error can pass a significance test; it explains nothing.)
- **Does the effect explain it?** The *excess* of a model's held-out error over the noise,
  ``E = S / n - 1`` (``S`` the sum of squared standardised held-out residuals over ``n``
  samples), is the part of the gap a model leaves. An effect that removes less than half of the
  nominal model's excess (:func:`explained_fraction` < ``min_explained``) does not explain the
  gap, however it ranks among the candidates: the verdict is ``unexplained``, with the fraction
  it did explain in the reason.
"""

from __future__ import annotations

import math

from .selection import NOMINAL, Verdict

__all__ = ["explained_fraction", "check_verdict", "MIN_EXPLAINED", "MIN_SHRINK"]

#: An effect must remove at least this share of the nominal held-out excess over the noise floor.
MIN_EXPLAINED = 0.5
#: Where the nominal model shows no significant gap, an effect must cut the held-out RMS by at
#: least this share (and significantly) to be named.
MIN_SHRINK = 0.05


def explained_fraction(ss_before: float, ss_after: float, n: int) -> float:
    """Share of the nominal model's held-out excess over the noise that a model removes.

    Parameters
    ----------
    ss_before, ss_after
        Sums of squared standardised held-out residuals of the nominal model and of the model
        with the effect, over the same ``n`` samples.
    n
        Number of held-out residuals.

    Returns
    -------
    float
        ``1 - max(E_after, 0) / E_before`` with ``E = ss / n - 1``; at most 1, negative when the
        effect predicts worse than the nominal model; NaN when the nominal model shows no excess
        (``E_before <= 0``: nothing to explain) or an input is not finite.
    """
    if n <= 0 or not (math.isfinite(ss_before) and math.isfinite(ss_after)):
        return math.nan
    e_before = ss_before / n - 1.0
    if e_before <= 0.0:
        return math.nan
    return 1.0 - max(ss_after / n - 1.0, 0.0) / e_before


def check_verdict(
    verdict: Verdict,
    *,
    gap_p: float,
    beats_nominal_p: float,
    shrink: float,
    explained: float,
    no_gap_confidence: float,
    alpha: float = 0.01,
    min_explained: float = MIN_EXPLAINED,
    min_shrink: float = MIN_SHRINK,
) -> tuple[Verdict, str | None]:
    """Apply the two checks of the module docstring to a verdict naming an effect.

    Parameters
    ----------
    verdict
        The verdict of :func:`~.selection.decide`; ``none`` and ``unexplained`` pass unchanged.
    gap_p
        p-value of the nominal model's held-out error against the noise floor.
    beats_nominal_p
        p-value that the named effect predicts the held-out data better than the nominal model.
    shrink
        ``1 - RMS_after / RMS_before`` of the standardised held-out residuals.
    explained
        :func:`explained_fraction` of the named effect.
    no_gap_confidence
        Confidence to give ``none`` when the first check demotes the verdict (e.g. one minus the
        discrepancy term's weight).
    alpha
        Significance level.
    min_explained
        Least share of the excess the named effect must remove.
    min_shrink
        Least held-out RMS shrink that names an effect where the nominal model shows no gap.

    Returns
    -------
    (Verdict, str or None)
        The checked verdict, and a note saying what changed (None when nothing did).
    """
    name = verdict.name
    if name in (NOMINAL, "unexplained"):
        return verdict, None
    gain = math.isfinite(shrink) and shrink >= min_shrink and beats_nominal_p < alpha
    if gap_p >= alpha and not gain:
        how = (
            f"cuts the held-out error by {100 * max(shrink, 0.0):.1f} % only"
            if beats_nominal_p < alpha
            else f"does not predict the held-out data significantly better (p = {beats_nominal_p:.2g})"
        )
        why = (
            f"the nominal model's held-out error is within the noise (p = {gap_p:.2g}) and {name} {how}: "
            f"there is no gap to explain"
        )
        return (
            Verdict(NOMINAL, float(min(1.0, max(0.0, no_gap_confidence))), why),
            f"{name} ranked first among the candidates, but {why}",
        )
    if math.isfinite(explained) and explained < min_explained:
        share = max(explained, 0.0)
        why = (
            f"the best candidate, {name}, removes only {100 * share:.0f} % of the nominal model's held-out "
            f"excess over the noise floor (at least {100 * min_explained:.0f} % is needed to say it explains "
            f"the gap)"
        )
        return (
            Verdict("unexplained", float(min(1.0, max(0.0, 1.0 - share))), why),
            f"{name} ranked first among the candidates, but {why}",
        )
    return verdict, None
