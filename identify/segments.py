"""A soil map along a long drive log: the log cut into segments, each fitted offline, neighbours that agree merged.

``segments="60s"`` cuts the log every 60 s of its time; ``"auto"`` where the on-line change detector
(:class:`~soiltrack.identify.online.OnlineEstimator`, replayed over the log) dates a change of terrain.
Each segment is fitted by :func:`~soiltrack.identify.fit` on its rows (the nominal drive-log fit, its
consistency checks and outcome). Neighbouring segments whose soils agree - both usable, and
``|F_max,1 - F_max,2|`` and ``|K_1 - K_2|`` within 1.96 standard errors of their difference (a 5 % test
of equality on each) - are merged into one and fitted again on their rows together, so a run over one soil
gives one row with the log's full precision, and a false alarm of the detector goes away (a run longer than
:data:`MERGE_REFIT_ROWS` rows pools its pieces' estimates instead of a refit: the memory stays bounded).

A drive log has one normal load: cohesion and friction angle are not separable (only
``F_max = A c + W tan(phi)`` and K are), so ``cohesion_kpa`` and ``friction_angle_deg`` are null unless a
fit identifies them.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..soilmodel.data import DriveLog
from ..soilmodel.errors import DataError
from ..soilmodel.vehicle import Vehicle

__all__ = [
    "Segment",
    "SegmentMap",
    "parse_segments",
    "segment_edges",
    "detected_changes",
    "fit_segments",
    "SEGMENT_FIELDS",
    "log_span",
    "segment_of",
]

#: The fields of one segment, in the order of the CSV columns (docs/drivelogs.md, "Long logs").
SEGMENT_FIELDS = (
    "start_s",
    "end_s",
    "distance_m",
    "max_thrust_N",
    "max_thrust_ci95",
    "shear_modulus_m",
    "shear_modulus_ci95",
    "cohesion_kpa",
    "friction_angle_deg",
    "outcome",
)
#: Shortest segment the automatic cut makes, s (the change detector's dating is good to a few seconds;
#: a shorter piece is joined to its neighbour).
MIN_AUTO_SEGMENT_S = 10.0
#: Most rows of a merged run fitted again as one; a longer run pools its pieces' estimates (precision-weighted),
#: so the memory of a segment map is that of the log and one fit of at most this many rows.
MERGE_REFIT_ROWS = 100_000
#: Length of the pieces ``auto`` cuts between detected changes, s.
AUTO_GRID_S = 60.0
#: Two soils "agree" when each of F_max and K differs by at most this many standard errors of the difference.
AGREE_Z = 1.96


@dataclass(frozen=True)
class Segment:
    """One segment's soil: the :data:`SEGMENT_FIELDS` plus rows, merged pieces and the outcome's reason."""

    start_s: float
    end_s: float
    distance_m: float
    max_thrust_N: float | None
    max_thrust_ci95: tuple[float, float] | None
    shear_modulus_m: float | None
    shear_modulus_ci95: tuple[float, float] | None
    cohesion_kpa: float | None
    friction_angle_deg: float | None
    outcome: str
    rows: int
    pieces: int
    reason: str | None
    max_thrust_stderr_N: float | None = None
    shear_modulus_stderr_m: float | None = None
    not_identified: tuple[tuple[str, str], ...] = ()
    """``(name, why)`` of F_max / K the fit does not determine (their fields are then null)."""
    discretisation: str | None = None
    """The held-torque discretisation of the reported fit (``"end-point"`` or ``"relaxation"``: the fit's own
    check, :func:`~soiltrack.identify.drivelog.fit.fit_drive_log`); None without a fit, several joined by "+"
    for a merged run pooled from its pieces."""

    def to_dict(self) -> dict:
        """JSON fields (never NaN)."""
        d = {k: getattr(self, k) for k in SEGMENT_FIELDS}
        for k in ("max_thrust_ci95", "shear_modulus_ci95"):
            d[k] = None if d[k] is None else [float(x) for x in d[k]]
        d.update(
            rows=self.rows,
            pieces=self.pieces,
            outcome_reason=self.reason,
            max_thrust_stderr_N=self.max_thrust_stderr_N,
            shear_modulus_stderr_m=self.shear_modulus_stderr_m,
            not_identified=dict(self.not_identified),
            discretisation=self.discretisation,
        )
        return d


@dataclass(frozen=True)
class SegmentMap:
    """Segments of a log in time order; ``spec`` as given, ``cuts`` the times it was cut at before merging."""

    segments: tuple[Segment, ...]
    spec: str
    cuts: tuple[float, ...]
    source: str | None

    def to_dict(self) -> dict:
        return {
            "source": self.source,
            "segments_spec": self.spec,
            "cuts_s": list(self.cuts),
            "segments": [s.to_dict() for s in self.segments],
        }


def parse_segments(text: str) -> float | None:
    """``"60s"`` (or ``"60"``, ``"2min"``) -> seconds; ``"auto"`` -> None; DataError otherwise."""
    t = str(text).strip().lower()
    if t == "auto":
        return None
    m = re.fullmatch(r"([0-9]*\.?[0-9]+)\s*(s|min|h)?", t)
    if not m:
        raise DataError(f"--segments expects a duration (e.g. 60s, 5min) or auto, got {text!r}")
    val = float(m.group(1)) * {"s": 1.0, None: 1.0, "min": 60.0, "h": 3600.0}[m.group(2)]
    if not (math.isfinite(val) and val > 0):
        raise DataError(f"--segments expects a duration > 0, got {text!r}")
    return val


def _grid(t0: float, t1: float, length_s: float) -> list[float]:
    """``t0, t0 + L, ...`` and ``t1``; a last piece shorter than a quarter of ``L`` is joined to the one before."""
    k = max(int(math.ceil((t1 - t0) / length_s - 1e-9)), 1)
    edges = [t0 + j * length_s for j in range(k)] + [t1]
    if len(edges) > 2 and t1 - edges[-2] < 0.25 * length_s:
        del edges[-2]
    return edges


def detected_changes(log: DriveLog, vehicle: Vehicle) -> list[float]:
    """Times of the changes of terrain the on-line estimator dates when the log is replayed through it, s."""
    from .online import OnlineEstimator

    est = OnlineEstimator(vehicle)
    update = est.update
    acc = log.vehicle_accel
    for j in range(log.n_samples):
        update(
            float(log.time[j]),
            float(log.sprocket_torque[j]),
            float(log.sprocket_speed[j]),
            float(log.vehicle_speed[j]),
            None if acc is None else float(acc[j]),
        )
    return sorted(float(c["time_s"]) for c in est.changes)


def segment_edges(log: DriveLog, vehicle: Vehicle, length_s: float | None) -> np.ndarray:
    """Cut times of the log (start and end included): every ``length_s`` s, or (None: ``auto``) at every change of
    terrain the on-line detector dates and every :data:`AUTO_GRID_S` s between them (the merge then joins the
    pieces of one soil: a change the detector misses is still found, a false alarm merged away)."""
    t0, t1 = float(log.time[0]), float(log.time[-1])
    if length_s is not None:
        return np.array(_grid(t0, t1, length_s))
    changes = [c for c in detected_changes(log, vehicle) if t0 + MIN_AUTO_SEGMENT_S <= c <= t1 - MIN_AUTO_SEGMENT_S]
    edges: list[float] = []
    for a, b in zip([t0] + changes, changes + [t1]):
        if b - a < MIN_AUTO_SEGMENT_S and edges:
            continue
        edges.extend(_grid(a, b, AUTO_GRID_S)[:-1])
    return np.array(edges + [t1])


#: The soil fields of a segment without an estimate.
_EMPTY: dict[str, Any] = dict(
    max_thrust_N=None,
    max_thrust_ci95=None,
    shear_modulus_m=None,
    shear_modulus_ci95=None,
    cohesion_kpa=None,
    friction_angle_deg=None,
)


def _distance(log: DriveLog, idx: np.ndarray) -> float:
    t, v = log.time[idx], log.vehicle_speed[idx]
    return float(np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(t))) if idx.size > 1 else 0.0


def _fit_piece(log: DriveLog, vehicle: Vehicle, idx: np.ndarray, pieces: int, options: dict) -> Segment:
    """One segment's fit (``identify.fit`` on its rows) as a :class:`Segment`."""
    from .fitting import fit

    base = log_span(log, idx)
    empty = dict(_EMPTY)
    try:
        res = fit(log.subset(idx), vehicle, **options)
    except DataError as e:
        return Segment(**base, **empty, outcome="failed", pieces=pieces, reason=str(e))
    return segment_of(res, base, pieces)


def log_span(log: DriveLog, idx: np.ndarray | None = None) -> dict[str, Any]:
    """``start_s``, ``end_s``, ``distance_m`` and ``rows`` of the rows ``idx`` of a log (all rows by default)."""
    idx = np.arange(log.n_samples) if idx is None else idx
    if idx.size == 0:
        return dict(start_s=None, end_s=None, distance_m=0.0, rows=0)
    return dict(
        start_s=float(log.time[idx[0]]),
        end_s=float(log.time[idx[-1]]),
        distance_m=_distance(log, idx),
        rows=int(idx.size),
    )


def segment_of(res: Any, base: dict[str, Any], pieces: int = 1) -> Segment:
    """A fit result as a :class:`Segment` (``base``: its :func:`log_span`); a failed fit's reason kept."""
    empty = dict(_EMPTY)
    if res.status == "not fitted":  # fit_many's failed item: nothing was solved
        return Segment(**base, **empty, outcome="failed", pieces=pieces, reason=res.message)
    d = res.to_dict()
    if not res.success:
        reason = d.get("outcome_reason") or res.message
        return Segment(**base, **empty, outcome=str(d["outcome"]), pieces=pieces, reason=str(reason))
    comb = {c["name"].split("@")[0]: c for c in d["combinations"]}
    par = d["parameters"]

    def ident(name: str) -> float | None:
        p = par.get(name) or {}
        return float(p["value"]) if p.get("identifiable") and p.get("value") is not None else None

    def ci(c: dict) -> tuple[float, float] | None:
        lo, hi = c.get("ci95") or (None, None)
        return None if lo is None or hi is None else (float(lo), float(hi))

    F, K = comb.get("F_max", {}), comb.get("K", {})
    # only what the outcome rules call determined is reported (and merged on): a gentle piece's F_max, a K on
    # its bound (F_max's interval then holds K at the bound) are null, with the reason in ``not_identified``
    okF, okK = bool(F.get("determined")), bool(K.get("determined"))
    missing = tuple(
        (k, str(c.get("not_determined_reason") or "not determined"))
        for k, c, ok in (("F_max", F, okF), ("K", K, okK))
        if not ok
    )
    return Segment(
        **base,
        max_thrust_N=F.get("value") if okF else None,
        max_thrust_ci95=ci(F) if okF else None,
        shear_modulus_m=K.get("value") if okK else None,
        shear_modulus_ci95=ci(K) if okK else None,
        cohesion_kpa=ident("cohesion_kpa"),
        friction_angle_deg=ident("friction_angle_deg"),
        outcome=str(d["outcome"]),
        pieces=pieces,
        reason=None,
        max_thrust_stderr_N=F.get("stderr") if okF else None,
        shear_modulus_stderr_m=K.get("stderr") if okK else None,
        not_identified=missing,
        discretisation=res.extra.get("discretisation"),
    )


def _combined(log: DriveLog, idx: np.ndarray, parts: list[Segment]) -> Segment:
    """A merged run too long to fit again: F_max and K as the precision-weighted means of its pieces' (independent
    fits of disjoint rows), standard errors ``1 / sqrt(sum 1 / se^2)``, normal 95 % intervals."""

    def pool(vals, ses):
        w = np.array([1.0 / se**2 for se in ses])
        m = float(np.sum(w * np.array(vals)) / np.sum(w))
        se = float(1.0 / math.sqrt(np.sum(w)))
        return m, se, (m - 1.959963984540054 * se, m + 1.959963984540054 * se)

    F, sF, ciF = pool([p.max_thrust_N for p in parts], [p.max_thrust_stderr_N for p in parts])
    K, sK, ciK = pool([p.shear_modulus_m for p in parts], [p.shear_modulus_stderr_m for p in parts])
    return Segment(
        start_s=parts[0].start_s,
        end_s=parts[-1].end_s,
        distance_m=_distance(log, idx),
        max_thrust_N=F,
        max_thrust_ci95=ciF,
        shear_modulus_m=K,
        shear_modulus_ci95=ciK,
        cohesion_kpa=None,
        friction_angle_deg=None,
        outcome=parts[0].outcome,
        rows=int(idx.size),
        pieces=len(parts),
        reason=None,
        max_thrust_stderr_N=sF,
        shear_modulus_stderr_m=sK,
        discretisation="+".join(sorted({p.discretisation for p in parts if p.discretisation})) or None,
    )


def _agree(a: Segment, b: Segment) -> bool:
    """Both usable and F_max and K equal within :data:`AGREE_Z` standard errors of their differences."""
    if a.reason is not None or b.reason is not None:
        return False
    for va, vb, sa, sb in (
        (a.max_thrust_N, b.max_thrust_N, a.max_thrust_stderr_N, b.max_thrust_stderr_N),
        (a.shear_modulus_m, b.shear_modulus_m, a.shear_modulus_stderr_m, b.shear_modulus_stderr_m),
    ):
        if va is None or vb is None or sa is None or sb is None:
            return False
        if abs(va - vb) > AGREE_Z * math.hypot(sa, sb):
            return False
    return True


def fit_segments(
    log: DriveLog, vehicle: Vehicle, segments: str | float | None, *, merge: bool = True, **options: Any
) -> SegmentMap:
    """The soil along a drive log, segment by segment (see the module notes).

    Parameters
    ----------
    log, vehicle
        The drive log and its vehicle.
    segments
        ``"60s"``-style duration, a number of seconds, or ``"auto"`` / None (cut at detected changes).
    merge
        Merge neighbouring segments whose soils agree, and fit them again together.
    **options
        Passed to :func:`~soiltrack.identify.fit` for every segment (e.g. ``bounds``).
    """
    spec = segments if isinstance(segments, str) else ("auto" if segments is None else f"{float(segments):g}s")
    length = parse_segments(segments) if isinstance(segments, str) else segments
    edges = segment_edges(log, vehicle, length)
    t = log.time
    groups: list[np.ndarray] = []
    for j in range(edges.size - 1):
        last = j == edges.size - 2
        mask = (t >= edges[j]) & ((t <= edges[j + 1]) if last else (t < edges[j + 1]))
        idx = np.nonzero(mask)[0]
        if idx.size:
            groups.append(idx)
    # the profiled fit (the same optimum as IPOPT's latent slips, measured to 9 digits) at any segment length
    options = {"latent_slips": "profiled", **options}
    fitted = [_fit_piece(log, vehicle, g, 1, options) for g in groups]
    if merge and len(fitted) > 1:
        runs: list[list[int]] = [[0]]
        for j in range(1, len(fitted)):
            if _agree(fitted[runs[-1][-1]], fitted[j]):
                runs[-1].append(j)
            else:
                runs.append([j])
        out = []
        for run in runs:
            if len(run) == 1:
                out.append(fitted[run[0]])
            else:
                idx = np.concatenate([groups[j] for j in run])
                if idx.size <= MERGE_REFIT_ROWS:
                    out.append(_fit_piece(log, vehicle, idx, len(run), options))
                else:
                    out.append(_combined(log, idx, [fitted[j] for j in run]))
        fitted = out
    return SegmentMap(segments=tuple(fitted), spec=spec, cuts=tuple(float(e) for e in edges[1:-1]), source=log.source)
