#!/usr/bin/env python
"""Rebuild the seed paper's evidence with soiltrack, and say where it holds and where it does not.

The seed: "Traversability prediction for unmanned ground vehicles based on identified soil
parameters" (IFAC 2005), which identifies c, phi and K of Eq. 2 from three points of Wong
(2001, p. 176) with Newton-Raphson and least squares.

Usage (from the repository root)::

    python examples/reproduce_paper.py                       # full run, examples/out/paper/
    python examples/reproduce_paper.py --quick --out /tmp/p  # smoke run (fewer draws/starts)
    python examples/reproduce_paper.py --draws 5000 --starts 200

Writes ``DIR/report.md`` and the figures ``DIR/fig2_backprediction.png`` ...
``DIR/fig7_traversability.png``. Every number in the report is computed in the run (the seed's
own numbers are quoted as such). Progress goes to stderr.

Assumptions, stated wherever they matter: the heavy vehicle (W = 329 kN, Wong 2001 p. 176)
has l = 2.8 m and b = 0.5 m - the seed gives neither; the light vehicle (W = 300 N) has
l = 0.5 m, b = 0.1 m.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if _ROOT not in sys.path:  # run from a source checkout without installing
    sys.path.insert(0, _ROOT)

from soiltrack.soilmodel import (  # noqa: E402
    PRACTICAL_BOUNDS,
    SEED_ACTUAL,
    TERRAINS,
    VEHICLES,
    SlipData,
    Soil,
    max_thrust,
    tractive_force,
    tractive_force_sensitivities,
)

# --------------------------------------------------------------------------------------------
# reference data (docs/physics.md)
# --------------------------------------------------------------------------------------------
WONG_SLIP = np.array([0.0248, 0.0344, 0.0700])
WONG_FORCE = np.array([207.32e3, 223.81e3, 259.81e3])  # N
HEAVY, LIGHT = VEHICLES["heavy"], VEHICLES["light"]

#: The seed's Table 1 as printed (quoted, not computed).
SEED_TABLE1 = {
    "newton": dict(c=0.65, phi=40.08, K=0.0182, time=0.016, err=(18.18, 0.05, 1.11)),
    "least-squares": dict(c=16.48, phi=34.78, K=0.0185, time=0.156, err=(2896, 13.27, 2.78)),
}
SEED_TABLE2 = dict(c=18.18, phi=2.22, K=4.44)
SEED_FIG2 = (-0.7, 1.0)
SEED_FIG6 = {"cohesion-free": (-0.4, 1.4), "full": (-1.0, 0.8)}

#: Initial vector of Table 1. The seed names only c0 = 0.65 kPa (Sect. 5: "the cohesion values
#: do not change much from its initial condition value (0.65 kPa)"); phi0 and K0 are ours.
X0_C_KPA, X0_PHI_DEG, X0_K_M = 0.65, 35.0, 0.025

DRIVETRAIN_MAX = 120e3  # N, the seed's "UGV able to produce 120 kN"
ACCEPTABLE_SLIP = 0.20  # slip up to which soil thrust counts as available (our choice, stated)
SLOPE_DEG = 15.0

METHOD_LABEL = {
    ("newton", "full"): "Newton-Raphson (seed's method), full model",
    ("least-squares", "full"): "least squares, full model",
    ("ipopt", "full"): "IPOPT (bounded), full model",
    ("ipopt", "cohesion-free"): "IPOPT (bounded), cohesion-free model",
    ("newton", "cohesion-free"): "Newton (Gauss-Newton, 3 eq. > 2 unknowns, unbounded), cohesion-free model",
}
#: (method, model, start) rows of Table 1; "seed" = the Table 1 start vector, "default" = library's start.
TABLE1_ROWS = (
    ("newton", "full", "seed"),
    ("least-squares", "full", "seed"),
    ("ipopt", "full", "default"),
    ("ipopt", "full", "seed"),
    ("ipopt", "cohesion-free", "default"),
    ("newton", "cohesion-free", "seed"),
)
#: (method, model) of the noise study and the robustness test.
NOISE_ROWS = (("ipopt", "full"), ("ipopt", "cohesion-free"), ("newton", "full"), ("newton", "cohesion-free"))


def row_label(r) -> str:
    start = "Table 1 start vector" if r["start"] == "seed" else "library's default start"
    return f"{METHOD_LABEL[(r['method'], r['model'])]}, {start}"


def ca_version() -> str:
    import casadi

    return casadi.__version__


def log(msg: str) -> None:
    print(f"[reproduce_paper {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def pct(model, data):
    return (np.asarray(model) - np.asarray(data)) / np.asarray(data) * 100.0


def fmt(x, spec=".4g", none="-"):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return none
    return format(x, spec)


def q(a, p):
    a = np.asarray(a, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.percentile(a, p)) if a.size else math.nan


def with_length(vehicle, l):
    return dataclasses.replace(vehicle, track_length=float(l))


# --------------------------------------------------------------------------------------------
# identify adaptors (soiltrack.identify contract)
# --------------------------------------------------------------------------------------------
def _identify():
    from soiltrack import identify

    return identify


def x0_vector(c_kpa, phi_deg, K_m):
    """Initial vector [c (Pa), phi (rad), K (m)] as identify.fit takes it."""
    return np.array([c_kpa * 1e3, math.radians(phi_deg), K_m], dtype=float)


def do_fit(data, model, method, x0=None, vehicle=HEAVY):
    return _identify().fit(data, vehicle, model=model, method=method, bounds=PRACTICAL_BOUNDS, x0=x0)


def combo(res, prefix):
    for cb in res.combinations:
        if cb.name == prefix or cb.name.startswith(prefix + "@"):
            return cb
    return None


def theta_finite(res):
    return bool(np.all(np.isfinite(np.asarray(res.theta, dtype=float))))


def fmax_of(res):
    cb = combo(res, "F_max")
    return cb.value if (cb is not None and theta_finite(res)) else math.nan


def k_of(res):
    return float(res.theta[2]) if theta_finite(res) else math.nan


def param_cell(res, name):
    """Text for one parameter: value +- stderr, 'not identifiable (ridge [a, b])', or '-'."""
    pe = res.parameters[name]
    u, fac, spec = {
        "cohesion": ("kPa", 1e-3, ".4g"),
        "friction_angle": ("deg", 180 / math.pi, ".4g"),
        "shear_modulus": ("m", 1.0, ".4g"),
    }[name]
    if pe.fixed:
        return "0 (fixed by the model)"
    if not res.success:
        v = res.theta[list(("cohesion", "friction_angle", "shear_modulus")).index(name)]
        return f"no estimate (solver point {fmt(v * fac, spec)} {u})"
    lo, hi = pe.ci95
    if not pe.identifiable:
        out = "NOT IDENTIFIABLE"
        rg = ridge_at(fmax_of(res)) if name in ("cohesion", "friction_angle") and math.isfinite(fmax_of(res)) else None
        if rg is not None:
            a, b = rg[0] if name == "cohesion" else rg[1]
            out += f": ridge {a * fac:.3g}-{b * fac:.3g} {u} at the F_max estimate"
        if lo is not None:
            out += f"; library's range {lo * fac:.3g}-{hi * fac:.3g} {u}"
        return out
    s = f"{pe.value * fac:{spec}}"
    if pe.stderr is not None:
        s += f" +- {pe.stderr * fac:.2g}"
    s += f" {u}"
    if pe.at_bound:
        s += f" (ON {pe.bound_side.upper()} BOUND)"
    return s


# --------------------------------------------------------------------------------------------
# sections
# --------------------------------------------------------------------------------------------
def jacobian_check(soil, vehicle=HEAVY):
    """Singular values and the c-phi column correlation of dF/d[c, phi, K] at the three points."""
    J = tractive_force_sensitivities(WONG_SLIP, soil, vehicle)  # (3, 3), N/Pa, N/rad, N/m
    s_raw = np.linalg.svd(J, compute_uv=False)
    Js = J / np.linalg.norm(J, axis=0)
    s_scaled = np.linalg.svd(Js, compute_uv=False)
    corr = float(np.dot(Js[:, 0], Js[:, 1]))
    # the exact proportionality: dF/dphi = (W sec^2 phi / A) dF/dc
    ratio = J[:, 1] / J[:, 0]
    return dict(
        J=J,
        s_raw=s_raw,
        s_scaled=s_scaled,
        corr=corr,
        ratio=ratio,
        cond=float(s_raw[0] / s_raw[-1]) if s_raw[-1] > 0 else math.inf,
    )


def ridge_at(fmax, vehicle=HEAVY, bounds=PRACTICAL_BOUNDS):
    """(c range in Pa, phi range in rad) of A c + W tan(phi) = fmax inside the bounds, or None."""
    A, W = vehicle.contact_area, vehicle.weight
    (c_lo, c_hi), (p_lo, p_hi) = bounds.cohesion, bounds.friction_angle
    c_a, c_b = max(c_lo, (fmax - W * math.tan(p_hi)) / A), min(c_hi, (fmax - W * math.tan(p_lo)) / A)
    if c_a > c_b:
        return None
    return (c_a, c_b), (math.atan((fmax - A * c_b) / W), math.atan((fmax - A * c_a) / W))


def ridge_point_text(ri, fmax):
    """Plain words on where the converged IPOPT full-model fits put (c, phi) on the ridge."""
    rg = ridge_at(fmax) if math.isfinite(fmax) else None
    if ri["c"].size == 0 or rg is None:
        return ""
    c_mid = 0.5 * (rg[0][0] + rg[0][1]) / 1e3
    spread = float(np.max(ri["c"]) - np.min(ri["c"]))
    if spread < 1e-3 and abs(float(np.median(ri["c"])) - c_mid) < 1e-2:
        return (
            f"The (c, phi) reported with them is the same for every start: c = {np.median(ri['c']):.4g} kPa, "
            f"phi = {np.median(ri['phi']):.4g} deg, the centre of the bounds-feasible ridge segment "
            f"({rg[0][0] / 1e3:.3g}-{rg[0][1] / 1e3:.3g} kPa) - a convention of the library, labelled as not an "
            "estimate, not something the data decide."
        )
    return (
        f"The (c, phi) reported with them spreads over c {np.min(ri['c']):.3g}-{np.max(ri['c']):.3g} kPa along "
        f"the ridge (bounds-feasible segment {rg[0][0] / 1e3:.3g}-{rg[0][1] / 1e3:.3g} kPa): where the solver's path "
        "meets the ridge, decided by the algorithm, the start and the bounds, not by the data."
    )


def scan_track_length(soil=SEED_ACTUAL, vehicle=HEAVY):
    """max |residual| (%) of the seed's actual parameters vs the track length l (b fixed)."""

    def worst(l):
        e = pct(tractive_force(WONG_SLIP, soil, with_length(vehicle, l)), WONG_FORCE)
        return float(np.max(np.abs(e))), e

    grid = np.arange(0.5, 10.0001, 0.01)
    w = np.array([worst(l)[0] for l in grid])
    k = int(np.argmin(w))
    fine = np.linspace(grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)], 2001)
    wf = np.array([worst(l)[0] for l in fine])
    kf = int(np.argmin(wf))
    l_best = float(fine[kf])
    return dict(
        grid=grid,
        worst=w,
        l_best=l_best,
        worst_best=float(wf[kf]),
        e_best=worst(l_best)[1],
        e_28=worst(vehicle.track_length)[1],
        worst_28=worst(vehicle.track_length)[0],
    )


def table1(args):
    data = SlipData(WONG_SLIP, WONG_FORCE, source="Wong (2001) p. 176")
    x0 = x0_vector(X0_C_KPA, X0_PHI_DEG, X0_K_M)
    rows = []
    for method, model, start in TABLE1_ROWS:
        log(f"Table 1: {method} / {model} ({start} start)")
        xs = x0 if start == "seed" else None
        res = do_fit(data, model, method, x0=xs)
        times, walls = [], []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            r2 = do_fit(data, model, method, x0=xs)
            walls.append(time.perf_counter() - t0)
            times.append(r2.solve_time)
        rows.append(
            dict(
                method=method,
                model=model,
                start=start,
                res=res,
                solve_med=float(np.median(times)),
                wall_med=float(np.median(walls)),
                first_time=res.solve_time,
            )
        )
    return data, x0, rows


def newton_from_seed_start(data):
    """The library's Newton method started at c = 0.65 kPa: does c move? is J singular?"""
    x0 = x0_vector(X0_C_KPA, X0_PHI_DEG, X0_K_M)
    res = do_fit(data, "full", "newton", x0=x0)
    jc = jacobian_check(Soil(x0[0], x0[1], x0[2]))
    return res, jc


def noise_study(args, clean):
    """Table 2: +-3 % uniform white noise on F and i, many draws, with fit_many."""
    identify = _identify()
    rng = np.random.default_rng(args.seed)
    sets = []
    for _ in range(args.draws):
        uF = rng.uniform(-0.03, 0.03, 3)
        ui = rng.uniform(-0.03, 0.03, 3)
        sets.append(SlipData(WONG_SLIP * (1 + ui), WONG_FORCE * (1 + uF), source="noisy Wong"))
    out = {}
    for method, model in NOISE_ROWS:
        log(f"Table 2: {args.draws} noisy draws, {method} / {model} (fit_many)")
        t0 = time.perf_counter()
        kw = {}
        if method == "newton":
            kw["x0"] = x0_vector(X0_C_KPA, X0_PHI_DEG, X0_K_M)
        res = fit_many_compat(identify, sets, model, method, **kw)
        wall = time.perf_counter() - t0
        ok = np.array([r.success and theta_finite(r) for r in res])
        fm = np.array([fmax_of(r) for r in res])
        K = np.array([k_of(r) for r in res])
        th = np.array([np.asarray(r.theta, float) for r in res])
        ref = clean[(method, model)]
        if not (ref.success and theta_finite(ref)):  # e.g. Newton on the full model: use the IPOPT fit
            ref = clean[("ipopt", model)]
        fm0, K0 = fmax_of(ref), k_of(ref)
        fm_act = max_thrust(SEED_ACTUAL, HEAVY, model=model)
        on_bound = np.array([bool(r.active_bounds) for r in res])
        ident_cphi = np.array([r.parameters["cohesion"].identifiable for r in res])
        out[(method, model)] = dict(
            n=len(res),
            success=int(ok.sum()),
            wall=wall,
            fm_err=pct(fm[ok], fm0),
            K_err=pct(K[ok], K0),
            fm_err_act=pct(fm[ok], fm_act),
            K_err_act=pct(K[ok], SEED_ACTUAL.shear_modulus),
            c=th[ok, 0] / 1e3,
            phi=np.degrees(th[ok, 1]),
            c_err_act=np.abs(pct(th[ok, 0], SEED_ACTUAL.cohesion)),
            phi_err_act=np.abs(pct(th[ok, 1], SEED_ACTUAL.friction_angle)),
            K_abs_err_act=np.abs(pct(K[ok], SEED_ACTUAL.shear_modulus)),
            on_bound=int(on_bound[ok].sum()),
            cphi_identifiable=int(ident_cphi[ok].sum()),
            fm0=fm0,
            K0=K0,
            statuses=_count([r.status for r in res]),
        )
    return out


def fit_many_compat(identify, sets, model, method, **kw):
    """``fit_many`` with the practical bounds (extra keywords such as x0 go to each ``fit``)."""
    return identify.fit_many(sets, HEAVY, model=model, method=method, bounds=PRACTICAL_BOUNDS, progress=True, **kw)


def _count(items):
    out = {}
    for s in items:
        out[s] = out.get(s, 0) + 1
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def robustness(args, data):
    """100 random initial vectors in [0, 89]: c in kPa, phi in deg, K in m (literal) and in mm."""
    rng = np.random.default_rng(args.seed + 1)
    U = rng.uniform(0.0, 89.0, size=(args.starts, 3))
    out = {}
    for k_unit, k_fac in (("m", 1.0), ("mm", 1e-3)):
        starts = [x0_vector(u[0], max(u[1], 1e-6), max(u[2] * k_fac, 1e-9)) for u in U]
        for method, model in NOISE_ROWS:
            log(f"robustness: {len(starts)} starts (K in {k_unit}), {method} / {model}")
            res = []
            for x0 in starts:
                try:
                    res.append(do_fit(data, model, method, x0=x0))
                except Exception as e:  # a start the method refuses counts as not converged
                    res.append(e)
            fits = [r for r in res if not isinstance(r, Exception)]
            ok = [r for r in fits if r.success and theta_finite(r)]
            out[(k_unit, method, model)] = dict(
                n=len(starts),
                refused=len(res) - len(fits),
                converged=len(ok),
                statuses=_count(
                    [r.status for r in fits] + [f"refused: {type(r).__name__}" for r in res if isinstance(r, Exception)]
                ),
                fm=np.array([fmax_of(r) for r in ok]),
                K=np.array([k_of(r) for r in ok]),
                c=np.array([r.theta[0] / 1e3 for r in ok]),
                phi=np.degrees([r.theta[1] for r in ok]),
                c0_moved=np.array(
                    [
                        abs(r.theta[0] - x0[0])
                        for r, x0 in zip(res, starts)
                        if not isinstance(r, Exception) and r.success and theta_finite(r)
                    ]
                )
                / 1e3,
                rmse=np.array([r.rmse for r in ok]),
            )
    return U, out


def margins(vehicle=HEAVY):
    """Fig. 7 numbers: the seed's reading and the physically consistent margin."""
    rows = []
    for key in ("dry_sand", "clayey_soil"):
        soil = TERRAINS[key]
        seed_required = max_thrust(soil, vehicle)  # A c + W tan(phi): the seed's "required"
        for theta_deg in (0.0, SLOPE_DEG):
            th = math.radians(theta_deg)
            Wn = vehicle.weight * math.cos(th)
            soil_thrust = float(tractive_force(ACCEPTABLE_SLIP, soil, vehicle, normal_load=Wn))
            soil_limit = float(max_thrust(soil, vehicle, normal_load=Wn))
            available = min(DRIVETRAIN_MAX, soil_thrust)
            resistance = vehicle.weight * (vehicle.rolling_resistance * math.cos(th) + math.sin(th))
            rc = bekker_compaction(soil, vehicle, Wn)
            rows.append(
                dict(
                    key=key,
                    name=soil.name,
                    theta=theta_deg,
                    seed_required=seed_required,
                    seed_verdict=DRIVETRAIN_MAX >= seed_required,
                    soil_thrust=soil_thrust,
                    soil_limit=soil_limit,
                    available=available,
                    resistance=resistance,
                    margin=available - resistance,
                    go=available > resistance,
                    compaction=rc,
                    go_with_rc=available > resistance + rc,
                    K_typical=soil.shear_modulus_typical,
                    K=soil.shear_modulus,
                )
            )
    return rows


def bekker_compaction(soil, vehicle, Wn):
    """R_c = 2 b (k_c/b + k_phi) z0^(n+1)/(n+1), z0 = (p/(k_c/b + k_phi))^(1/n), p = W/A."""
    b, n = vehicle.track_width, soil.n
    k = soil.k_c / b + soil.k_phi
    z0 = (Wn / vehicle.contact_area / k) ** (1.0 / n)
    return 2.0 * b * k * z0 ** (n + 1) / (n + 1)


# --------------------------------------------------------------------------------------------
# figures
# --------------------------------------------------------------------------------------------
def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    log(f"wrote {path}")


def fig2(path, t1):
    fig, ax = plt.subplots(figsize=(7.5, 6.4))
    rows = [r for r in t1 if r["res"].success and theta_finite(r["res"])]
    width = 0.8 / (len(rows) + 1)
    xs = np.arange(3)
    e_act = pct(tractive_force(WONG_SLIP, SEED_ACTUAL, HEAVY), WONG_FORCE)
    ax.bar(xs - 0.4 + width / 2, e_act, width, label="seed's 'actual' c, phi, K (no fit)", color="0.6")
    for k, r in enumerate(rows):
        e = pct(r["res"].residuals + WONG_FORCE, WONG_FORCE)
        ax.bar(xs - 0.4 + width * (k + 1.5), e, width, label=row_label(r))
    ax.axhspan(*SEED_FIG2, color="tab:green", alpha=0.12, label="seed's Fig. 2 range (-0.7 to +1 %)")
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xticks(xs, [f"i = {i:.4g}\nF = {F / 1e3:.5g} kN" for i, F in zip(WONG_SLIP, WONG_FORCE)])
    ax.set_ylabel("back-predicted F error (%)\n(model - measured) / measured")
    ax.set_title(
        "Fig. 2: back-prediction at Wong's three points\n(heavy vehicle, l = 2.8 m, b = 0.5 m ASSUMED)", fontsize=10
    )
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=1)
    _save(fig, path)


def _variations(ax, vehicle, soil, which, slip, title):
    base = soil.as_vector()
    idx = {"c": 0, "phi": 1, "K": 2}[which]
    styles = [(-0.5, "--"), (0.0, "-"), (0.5, ":")]
    for f, ls in styles:
        v = base.copy()
        v[idx] *= 1 + f
        s = Soil(*v)
        lab = {
            "c": f"c = {s.cohesion_kpa:.3g} kPa",
            "phi": f"phi = {s.friction_angle_deg:.3g} deg",
            "K": f"K = {s.shear_modulus:.3g} m",
        }[which]
        unit = 1e3 if vehicle.weight > 1e4 else 1.0
        ax.plot(
            slip,
            tractive_force(slip, s, vehicle) / unit,
            ls,
            lw=1.6,
            label=f"{lab} ({'+' if f > 0 else ''}{f * 100:.0f} %)" if f else f"{lab} (nominal)",
        )
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("slip i (-)")
    ax.set_ylabel("F (kN)" if vehicle.weight > 1e4 else "F (N)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def normalised_sensitivities(vehicle, soil, slip):
    F = tractive_force(slip, soil, vehicle)
    S = tractive_force_sensitivities(slip, soil, vehicle)
    p = soil.as_vector()
    with np.errstate(invalid="ignore", divide="ignore"):
        return S * p[None, :] / F[:, None]


def fig3(path, slip):
    fig, axs = plt.subplots(2, 3, figsize=(12, 7.2))
    for ax, which in zip(axs[0], ("c", "phi", "K")):
        _variations(ax, HEAVY, SEED_ACTUAL, which, slip, f"heavy vehicle (W = 329 kN): {which} +-50 %")
    ax = axs[1, 0]
    Sn = normalised_sensitivities(HEAVY, SEED_ACTUAL, slip)
    for j, name in enumerate(("c", "phi", "K")):
        ax.plot(slip, Sn[:, j], lw=1.6, label=f"(p/F) dF/dp, p = {name}")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_title("normalised sensitivities, heavy vehicle", fontsize=9)
    ax.set_xlabel("slip i (-)")
    ax.set_ylabel("(p/F) dF/dp (-)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    ax = axs[1, 1]
    i0 = 0.07
    effects = []
    for which, j in (("c", 0), ("phi", 1), ("K", 2)):
        for f in (-0.5, 0.5):
            v = SEED_ACTUAL.as_vector()
            v[j] *= 1 + f
            effects.append(
                (
                    f"{which} {'+' if f > 0 else ''}{f * 100:.0f} %",
                    float(pct(tractive_force(i0, Soil(*v), HEAVY), tractive_force(i0, SEED_ACTUAL, HEAVY))),
                )
            )
    ax.barh(
        [e[0] for e in effects],
        [e[1] for e in effects],
        color=["tab:blue"] * 2 + ["tab:orange"] * 2 + ["tab:green"] * 2,
    )
    for k, (_, v) in enumerate(effects):
        ax.annotate(
            f"{v:+.2f} %",
            (v, k),
            xytext=(4 if v >= 0 else -4, 0),
            textcoords="offset points",
            ha="left" if v >= 0 else "right",
            va="center",
            fontsize=7,
        )
    ax.set_xlim(min(e[1] for e in effects) * 1.9, max(e[1] for e in effects) * 1.4)
    ax.axvline(0, color="k", lw=0.6)
    ax.set_xlabel(f"change of F at i = {i0} (%)")
    ax.set_title("effect of +-50 % on F, heavy vehicle", fontsize=9)
    ax.grid(alpha=0.3, axis="x")
    axs[1, 2].axis("off")
    axs[1, 2].text(
        0.0,
        0.95,
        "Soil: seed's 'actual' values\nc = 0.55 kPa, phi = 40.1 deg,\nK = 0.018 m.\n\n"
        "Heavy vehicle: W = 329 kN,\nl = 2.8 m, b = 0.5 m (ASSUMED),\nA = 2.8 m^2.\n\n"
        "phi +50 % (60 deg) is outside any\nreal soil; shown only as the\nseed's sensitivity device.",
        va="top",
        fontsize=9,
        transform=axs[1, 2].transAxes,
    )
    fig.suptitle("Fig. 3: sensitivity of the tractive force to c, phi and K (heavy vehicle)", fontsize=11)
    _save(fig, path)


def fig4(path, slip):
    fig, axs = plt.subplots(1, 3, figsize=(13, 4.3))
    _variations(axs[0], HEAVY, SEED_ACTUAL, "c", slip, "heavy (W = 329 kN, A = 2.8 m^2): c +-50 %")
    _variations(axs[1], LIGHT, SEED_ACTUAL, "c", slip, "light (W = 300 N, A = 0.1 m^2): c +-50 %")
    ax = axs[2]
    for veh, ls, lab in ((HEAVY, "-", "heavy"), (LIGHT, "--", "light")):
        Sn = normalised_sensitivities(veh, SEED_ACTUAL, slip)
        for j, (name, col) in enumerate((("c", "tab:blue"), ("phi", "tab:orange"), ("K", "tab:green"))):
            ax.plot(slip, Sn[:, j], ls, color=col, lw=1.5, label=f"{lab}: p = {name}")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xlabel("slip i (-)")
    ax.set_ylabel("(p/F) dF/dp (-)")
    ax.set_title("normalised sensitivities: heavy (solid) vs light (dashed)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.suptitle(
        "Fig. 4: effect of cohesion, heavy vs light vehicle (soil: seed's actual values; geometry ASSUMED)", fontsize=11
    )
    _save(fig, path)


def _fit_variants(t1):
    full = next(r["res"] for r in t1 if r["method"] == "ipopt" and r["model"] == "full" and r["start"] == "default")
    cf = next(r["res"] for r in t1 if r["method"] == "ipopt" and r["model"] == "cohesion-free")
    ncf = next(r["res"] for r in t1 if r["method"] == "newton" and r["model"] == "cohesion-free")
    out = [(full, "-", f"full (Eq. 2), IPOPT: F_max {fmax_of(full) / 1e3:.4g} kN, K {k_of(full):.4g} m")]
    out.append(
        (
            cf,
            "--",
            f"cohesion-free (Eq. 8), IPOPT bounded: phi {math.degrees(cf.theta[1]):.4g} deg"
            f"{' (on bound)' if cf.active_bounds else ''}, K {k_of(cf):.4g} m",
        )
    )
    if ncf.success and theta_finite(ncf):
        out.append(
            (
                ncf,
                "-.",
                f"cohesion-free (Eq. 8), unbounded Newton: phi {math.degrees(ncf.theta[1]):.4g} deg, "
                f"K {k_of(ncf):.4g} m",
            )
        )
    return out


def fig5_6(path5, path6, t1):
    variants = _fit_variants(t1)
    slip = np.linspace(0, 0.12, 300)
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for res, ls, lab in variants:
        pt = res.ridge_point if res.soil is None else res.soil
        ax.plot(slip, tractive_force(slip, pt, HEAVY, model=res.model) / 1e3, ls, lw=1.8, label=lab)
    ax.plot(
        slip,
        tractive_force(slip, SEED_ACTUAL, HEAVY) / 1e3,
        ":",
        color="0.4",
        lw=1.4,
        label="seed's 'actual' values, Eq. 2 (no fit)",
    )
    ax.plot(WONG_SLIP, WONG_FORCE / 1e3, "ko", ms=6, label="measured (Wong 2001 p. 176)")
    ax.set_xlabel("slip i (-)")
    ax.set_ylabel("tractive force F (kN)")
    ax.set_title(
        "Fig. 5: full vs cohesion-free model vs data\n(heavy vehicle, W = 329 kN, l = 2.8 m ASSUMED)", fontsize=10
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    _save(fig, path5)

    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    xs = np.arange(3)
    w = 0.8 / len(variants)
    for k, (res, _, lab) in enumerate(variants):
        e = pct(res.residuals + WONG_FORCE, WONG_FORCE)
        x = xs - 0.4 + w * (k + 0.5)
        ax.bar(x, e, w, label=lab)
        for xx, v in zip(x, e):
            ax.annotate(f"{v:+.2f}", (xx, v), ha="center", va="bottom" if v >= 0 else "top", fontsize=7)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xticks(xs, [f"i = {i:.4g}" for i in WONG_SLIP])
    ax.set_ylabel("(model - measured) / measured (%)")
    ax.set_title(
        "Fig. 6: % error of the fitted models at the measured points\n"
        "(seed: cohesion-free -0.4..+1.4 %, full -1..+0.8 %)",
        fontsize=10,
    )
    ax.grid(alpha=0.3, axis="y")
    lim = max(abs(ax.get_ylim()[0]), abs(ax.get_ylim()[1])) * 1.2
    ax.set_ylim(-lim, lim)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1))
    _save(fig, path6)


def fig7(path, rows):
    slip = np.linspace(0, 0.5, 400)
    fig, axs = plt.subplots(1, 3, figsize=(15, 4.8))
    cols = {"dry_sand": "tab:orange", "clayey_soil": "tab:brown"}
    ax = axs[0]
    for key in ("dry_sand", "clayey_soil"):
        soil = TERRAINS[key]
        F = tractive_force(slip, soil, HEAVY) / 1e3
        fm = max_thrust(soil, HEAVY) / 1e3
        ax.plot(slip, F, color=cols[key], lw=1.8, label=f"{soil.name}: A c + W tan(phi) = {fm:.0f} kN")
        ax.axhline(fm, color=cols[key], ls=":", lw=1)
    ax.axhline(DRIVETRAIN_MAX / 1e3, color="k", lw=1.5, label="UGV capability 120 kN")
    ax.text(
        0.25, 135, "seed: 120 kN < 178 kN 'required' -> not dry sand;\n120 kN > 88 kN -> clay", fontsize=7, ha="center"
    )
    ax.set_title("(a) as the seed draws it: soil thrust limit\nread as 'tractive force required'", fontsize=9)
    ax.set_xlabel("slip i (-)")
    ax.set_ylabel("tractive force (kN)")
    ax.set_ylim(0, 265)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    for ax, theta_deg in ((axs[1], 0.0), (axs[2], SLOPE_DEG)):
        th = math.radians(theta_deg)
        Wn = HEAVY.weight * math.cos(th)
        R = HEAVY.weight * (HEAVY.rolling_resistance * math.cos(th) + math.sin(th))
        for key in ("dry_sand", "clayey_soil"):
            soil = TERRAINS[key]
            F = tractive_force(slip, soil, HEAVY, normal_load=Wn)
            ax.plot(slip, F / 1e3, ":", color=cols[key], lw=1.2)
            ax.plot(
                slip,
                np.minimum(F, DRIVETRAIN_MAX) / 1e3,
                color=cols[key],
                lw=2,
                label=f"{soil.name}: available = min(120 kN, soil thrust)",
            )
        ax.axhline(R / 1e3, color="red", lw=1.5, label=f"resistance W(mu_r cos + sin theta) = {R / 1e3:.1f} kN")
        ax.axvline(ACCEPTABLE_SLIP, color="0.5", ls="--", lw=1, label=f"acceptable slip {ACCEPTABLE_SLIP:.2f}")
        for r in rows:
            if r["theta"] == theta_deg:
                ax.plot([ACCEPTABLE_SLIP], [r["available"] / 1e3], "o", color=cols[r["key"]])
                ax.annotate(
                    f"{'GO' if r['go'] else 'NO-GO'} ({r['margin'] / 1e3:+.0f} kN)",
                    (ACCEPTABLE_SLIP, r["available"] / 1e3),
                    xytext=(8, -12 if r["key"] == "clayey_soil" else 6),
                    textcoords="offset points",
                    fontsize=8,
                    color=cols[r["key"]],
                )
        ax.set_title(
            f"({'b' if theta_deg == 0 else 'c'}) physically consistent margin, "
            f"{'flat ground' if theta_deg == 0 else f'{theta_deg:.0f} deg slope'}\n"
            "(dotted: soil thrust alone)",
            fontsize=9,
        )
        ax.set_xlabel("slip i (-)")
        ax.set_ylim(0, 265)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    fig.suptitle(
        "Fig. 7: traversability, heavy vehicle (W = 329 kN, A = 2.8 m^2 ASSUMED, mu_r = 0.05); "
        "K of both soils typical values",
        fontsize=10,
    )
    _save(fig, path)


def fig_robustness(path, U, rob, fm_full):
    fig, axs = plt.subplots(1, 3, figsize=(14, 4.4))
    marks = {
        ("ipopt", "full"): "o",
        ("ipopt", "cohesion-free"): "s",
        ("newton", "full"): "x",
        ("newton", "cohesion-free"): "^",
    }
    for (k_unit, method, model), r in rob.items():
        if k_unit != "m":
            continue
        lab = f"{method}, {model}: {r['converged']}/{r['n']} converged"
        idx = np.arange(r["fm"].size)
        axs[0].plot(idx, r["fm"] / 1e3, marks[(method, model)], ms=4, mfc="none", label=lab)
        axs[1].plot(idx, r["K"] * 1e3, marks[(method, model)], ms=4, mfc="none", label=lab)
    axs[0].set_xlabel("converged start (index)")
    axs[0].set_ylabel("final F_max (kN)")
    axs[1].set_xlabel("converged start (index)")
    axs[1].set_ylabel("final K (mm)")
    axs[0].set_title("identifiable F_max: same from every start", fontsize=9)
    axs[1].set_title("identifiable K: same from every start", fontsize=9)
    ax = axs[2]
    ax.plot(U[:, 0], U[:, 1], "x", color="0.6", ms=4, label="starts (c0 kPa, phi0 deg)")
    r = rob[("m", "ipopt", "full")]
    ax.plot(r["c"], r["phi"], "o", color="tab:blue", ms=5, mfc="none", label="IPOPT full: final (c, phi)")
    rg = ridge_at(fm_full) if math.isfinite(fm_full) else None
    if rg is not None:
        cc = np.linspace(rg[0][0], rg[0][1], 100)
        ph = np.degrees(np.arctan((fm_full - HEAVY.contact_area * cc) / HEAVY.weight))
        ax.plot(cc / 1e3, ph, "-", color="tab:red", lw=1.5, label="ridge A c + W tan(phi) = F_max in bounds")
    ax.set_xlabel("c (kPa)")
    ax.set_ylabel("phi (deg)")
    ax.set_title("full model: starts and final points", fontsize=9)
    for ax in axs:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(
        "Robustness: random initial vectors in [0, 89] (c kPa, phi deg, K m); converged fits only", fontsize=10
    )
    _save(fig, path)


def fig_noise(path, noise):
    fig, axs = plt.subplots(1, 3, figsize=(14, 5.0))
    style = {
        ("ipopt", "full"): ("tab:blue", 3.5),
        ("ipopt", "cohesion-free"): ("tab:orange", 1.6),
        ("newton", "full"): ("tab:red", 1.6),
        ("newton", "cohesion-free"): ("tab:green", 1.2),
    }
    handles = {}
    for (method, model), r in noise.items():
        col, lw = style[(method, model)]
        lab = f"{method}, {model} ({r['success']}/{r['n']} succeeded)"
        handles[lab] = plt.Line2D([], [], color=col, lw=lw)
        for ax, v in ((axs[0], r["fm_err"]), (axs[1], r["K_err"])):
            v = v[np.isfinite(v)]
            if ax is axs[0] and (method, model) == ("ipopt", "cohesion-free"):
                ax.text(
                    0.02,
                    0.97,
                    f"ipopt, cohesion-free (not shown):\n{r['on_bound']}/{r['n']} fits end on the "
                    "phi bound,\nF_max = W tan(40 deg) is fixed\nby the bound, not by the data",
                    transform=ax.transAxes,
                    fontsize=7,
                    va="top",
                    color=col,
                )
                continue
            if v.size:
                ax.hist(v, bins=40, histtype="step", lw=lw, color=col, alpha=0.85)
        if model == "full" and r["c"].size:
            axs[2].plot(r["c"], r["phi"], ".", ms=3, alpha=0.5, color=col)
    axs[0].set_title("F_max (ipopt full and unbounded newton\ncohesion-free coincide)", fontsize=9)
    axs[1].set_title("K", fontsize=9)
    axs[0].set_ylim(0, axs[0].get_ylim()[1] * 1.45)
    axs[0].set_xlabel("F_max error vs noise-free fit (%)")
    axs[1].set_xlabel("K error vs noise-free fit (%)")
    axs[0].set_ylabel("number of draws")
    axs[2].set_xlabel("solver's c (kPa)")
    axs[2].set_ylabel("solver's phi (deg)")
    axs[2].set_title(
        "full model, ipopt: solver's (c, phi) = arbitrary ridge\npoints (not estimates; not identifiable)", fontsize=9
    )
    for ax in axs:
        ax.grid(alpha=0.3)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center", ncol=4, fontsize=8)
    fig.suptitle("Table 2 draws: +-3 % uniform noise on F and i (successful fits)", fontsize=10)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.savefig(path, dpi=120)
    plt.close(fig)
    log(f"wrote {path}")


# --------------------------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------------------------
def dist(a, spec=".3g", unit=""):
    a = np.asarray(a, dtype=float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return "-"
    return f"{np.median(a):{spec}} [{q(a, 5):{spec}}, {q(a, 95):{spec}}]{unit}"


def default_out(quick: bool) -> str:
    """Output folder when ``--out`` is not given: a ``--quick`` smoke run has its own."""
    return os.path.join(_ROOT, "examples", "out", "paper-quick" if quick else "paper")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--out",
        default=None,
        help="output folder (default examples/out/paper; with --quick "
        "examples/out/paper-quick, so a smoke run never overwrites the full report)",
    )
    ap.add_argument("--quick", action="store_true", help="smoke run: 50 draws, 20 starts, 3 timing repeats")
    ap.add_argument("--draws", type=int, default=None, help="noisy draws for Table 2 (default 1000; quick 50)")
    ap.add_argument("--starts", type=int, default=None, help="random initial vectors (default 100; quick 20)")
    ap.add_argument("--repeats", type=int, default=None, help="timing repeats per Table 1 row (default 30)")
    ap.add_argument("--seed", type=int, default=2005, help="random seed")
    args = ap.parse_args(argv)
    if args.out is None:
        args.out = default_out(args.quick)
    args.draws = args.draws if args.draws is not None else (50 if args.quick else 1000)
    args.starts = args.starts if args.starts is not None else (20 if args.quick else 100)
    args.repeats = args.repeats if args.repeats is not None else (3 if args.quick else 30)
    os.makedirs(args.out, exist_ok=True)
    t_start = time.perf_counter()
    P = lambda name: os.path.join(args.out, name)  # noqa: E731
    L: list[str] = []
    A = HEAVY.contact_area
    W = HEAVY.weight

    # ---- figures that need no identification
    slip = np.linspace(0.0, 0.3, 301)
    fig3(P("fig3_sensitivity_heavy.png"), slip)
    fig4(P("fig4_cohesion_heavy_vs_light.png"), slip)
    mrows = margins()
    fig7(P("fig7_traversability.png"), mrows)
    scan = scan_track_length()
    jc_act = jacobian_check(SEED_ACTUAL)

    # ---- identification
    data, x0, t1 = table1(args)
    clean = {(r["method"], r["model"]): r["res"] for r in t1 if not (r["method"] == "ipopt" and r["start"] == "seed")}
    nres, jc0 = newton_from_seed_start(data)
    fig2(P("fig2_backprediction.png"), t1)
    fig5_6(P("fig5_models_vs_data.png"), P("fig6_model_errors.png"), t1)
    noise = noise_study(args, clean)
    fig_noise(P("table2_noise.png"), noise)
    U, rob = robustness(args, data)
    fig_robustness(P("robustness.png"), U, rob, fmax_of(clean[("ipopt", "full")]))

    # ---------------------------------------------------------------------------- report
    e_act = pct(tractive_force(WONG_SLIP, SEED_ACTUAL, HEAVY), WONG_FORCE)
    L.append("# The seed paper rebuilt with soiltrack")
    L.append("")
    L.append(
        "Generated by `examples/reproduce_paper.py` "
        f"({'--quick, ' if args.quick else ''}{args.draws} noisy draws, {args.starts} random starts, "
        f"{args.repeats} timing repeats, random seed {args.seed}). Every number below is computed in this run, "
        "except those labelled *seed* (quoted from the seed paper, IFAC 2005). "
        f"casadi {ca_version()}, numpy {np.__version__}, Python {sys.version.split()[0]}."
    )
    L.append("")
    L.append(
        "**Assumptions.** Data: Wong (2001) p. 176, W = 329 kN, three points "
        + ", ".join(f"(i = {i:.4g}, F = {F / 1e3:.5g} kN)" for i, F in zip(WONG_SLIP, WONG_FORCE))
        + ". The seed gives neither the track length l nor the width b: this library's heavy reference "
        f"vehicle ASSUMES l = {HEAVY.track_length:g} m, b = {HEAVY.track_width:g} m (A = 2 b l = {A:g} m^2). "
        f"The light vehicle (W = {LIGHT.weight:.0f} N) ASSUMES l = {LIGHT.track_length:g} m, "
        f"b = {LIGHT.track_width:g} m (A = {LIGHT.contact_area:g} m^2). Bounds: the seed's practical ranges "
        f"c {PRACTICAL_BOUNDS.cohesion[0] / 1e3:g}-{PRACTICAL_BOUNDS.cohesion[1] / 1e3:g} kPa, "
        f"phi {math.degrees(PRACTICAL_BOUNDS.friction_angle[0]):g}-"
        f"{math.degrees(PRACTICAL_BOUNDS.friction_angle[1]):g} deg, K {PRACTICAL_BOUNDS.shear_modulus[0]:g}-"
        f"{PRACTICAL_BOUNDS.shear_modulus[1]:g} m. Errors in % are (model - measured) / measured."
    )
    L.append("")
    L.append(
        "With the seed's 'actual' values (c = 0.55 kPa, phi = 40.1 deg, K = 0.018 m) and l = 2.8 m, Eq. 2 "
        "gives "
        + ", ".join(
            f"{F / 1e3:.2f} kN ({e:+.2f} %)" for F, e in zip(tractive_force(WONG_SLIP, SEED_ACTUAL, HEAVY), e_act)
        )
        + " at the three points: the 'actual' values do not reproduce the data exactly (see the last section)."
    )
    L.append("")

    # ---- Table 1
    L.append("## Table 1 - identification on Wong's three points")
    L.append("")
    L.append(
        f"'Table 1 start vector': c0 = {X0_C_KPA} kPa (the seed's, Sect. 5), phi0 = {X0_PHI_DEG:g} deg, "
        f"K0 = {X0_K_M:g} m (phi0, K0 are not given by the seed; ours), used by Newton and least squares as in "
        "the seed, and by IPOPT in a second row. 'Library's default start': the variable-projection grid start "
        "of `soiltrack.identify.fit`. Newton and least squares are unbounded (as in the seed); IPOPT is bounded "
        f"by the practical ranges. Time: median over {args.repeats} repeated calls of the result's "
        "`solve_time` (compiled solvers reused) and of the wall-clock time of the whole `fit` call. "
        "'+-' is the linearised standard error."
    )
    L.append("")
    L.append(
        "| method | status | c | phi | K | F_max = A c + W tan(phi) (kN) | residuals (%) at the 3 points | "
        "iterations | solve time (ms) | wall per fit (ms) |"
    )
    L.append("|---|---|---|---|---|---|---|---|---|---|")
    for r in t1:
        res = r["res"]
        fm = combo(res, "F_max")
        fm_s = "-"
        if fm is not None and theta_finite(res) and res.success:
            fm_s = f"{fm.value / 1e3:.5g}" + (f" +- {fm.stderr / 1e3:.2g}" if fm.stderr is not None else "")
        e = pct(res.residuals + WONG_FORCE, WONG_FORCE) if np.all(np.isfinite(res.residuals)) else None
        e_s = ", ".join(f"{v:+.2f}" for v in e) if e is not None else "non-finite"
        if not res.success:
            e_s = f"at the solver's last point: {e_s}"
        L.append(
            f"| {row_label(r)} | {res.status}{'' if res.success else ' (FAILED)'} | "
            f"{param_cell(res, 'cohesion')} | {param_cell(res, 'friction_angle')} | "
            f"{param_cell(res, 'shear_modulus')} | {fm_s} | {e_s} | {res.iterations} | "
            f"{r['solve_med'] * 1e3:.3g} | {r['wall_med'] * 1e3:.3g} |"
        )
    L.append("")
    L.append("Seed's Table 1 (*seed*) and what it means, evaluated with this library (l = 2.8 m assumed):")
    L.append("")
    L.append(
        "| seed row | c (kPa) | phi (deg) | K (m) | seed's time (s) | F_max = A c + W tan(phi) (kN) | "
        "back-predicted errors (%) |"
    )
    L.append("|---|---|---|---|---|---|---|")
    seed_fm = {}
    for key, lab in (("newton", "Newton-Raphson"), ("least-squares", "least squares")):
        s = SEED_TABLE1[key]
        soil = Soil.from_kpa_deg(s["c"], s["phi"], s["K"])
        seed_fm[key] = max_thrust(soil, HEAVY)
        e = pct(tractive_force(WONG_SLIP, soil, HEAVY), WONG_FORCE)
        L.append(
            f"| {lab} (*seed*) | {s['c']} ({s['err'][0]} %) | {s['phi']} ({s['err'][1]} %) | "
            f"{s['K']} ({s['err'][2]} %) | {s['time']} | {seed_fm[key] / 1e3:.1f} | "
            + ", ".join(f"{v:+.2f}" for v in e)
            + " |"
        )
    fm_act = max_thrust(SEED_ACTUAL, HEAVY)
    L.append(
        f"| seed's 'actual' | 0.55 | 40.1 | 0.018 | - | {fm_act / 1e3:.1f} | "
        + ", ".join(f"{v:+.2f}" for v in e_act)
        + " |"
    )
    L.append("")
    L.append(
        f"The seed's two rows differ by {abs(SEED_TABLE1['least-squares']['c'] - SEED_TABLE1['newton']['c']):.2f} "
        f"kPa in c and {abs(SEED_TABLE1['least-squares']['phi'] - SEED_TABLE1['newton']['phi']):.2f} deg in phi, "
        f"yet their F_max differ by only {abs(seed_fm['newton'] - seed_fm['least-squares']) / 1e3:.1f} kN "
        f"({abs(seed_fm['newton'] - seed_fm['least-squares']) / seed_fm['newton'] * 100:.1f} %): both are points of "
        "(nearly) the same ridge A c + W tan(phi) = const. The least-squares c = 16.48 kPa is not 'diverged' "
        "and the Newton c = 0.65 kPa is not an estimate: c is not determined by these data at all."
    )
    L.append("")
    # Newton from the seed's start
    nth = np.asarray(nres.theta, float)
    L.append(
        "**The seed's c = 0.65 kPa is its initial guess.** The library's Newton method (the seed's Eq. 7) "
        f"started at c0 = {X0_C_KPA} kPa, phi0 = {X0_PHI_DEG:g} deg, K0 = {X0_K_M:g} m returns status "
        f"`{nres.status}` (success = {nres.success}, {nres.iterations} iterations); message: "
        f'"{nres.message}". Its final point: c = {fmt(nth[0] / 1e3)} kPa, phi = {fmt(math.degrees(nth[1]))} deg, '
        f"K = {fmt(nth[2])} m"
        + (f" (c moved by {abs(nth[0] - x0[0]) / 1e3:.3g} kPa from its start)" if math.isfinite(nth[0]) else "")
        + ". The Jacobian dF/d[c, phi, K] of the 3-by-3 system at the start (CasADi AD): singular values "
        + ", ".join(f"{s:.3g}" for s in jc0["s_raw"])
        + f" (condition number {jc0['cond']:.3g}); "
        f"column-scaled: "
        + ", ".join(f"{s:.3g}" for s in jc0["s_scaled"])
        + f"; correlation of the c and phi columns {jc0['corr']:.12f}. The phi column is exactly "
        f"W sec^2(phi)/A times the c column (ratio at the three points: "
        + ", ".join(f"{v:.6g}" for v in jc0["ratio"])
        + " N/rad per N/Pa): the Jacobian is singular, "
        "so Eq. 7 has no unique step and c cannot be updated by the data."
    )
    L.append("")
    for w in nres.warnings[:3]:
        L.append(f"> library warning (Newton): {w}")
    L.append("")
    full_res = clean[("ipopt", "full")]
    cf_res = clean[("ipopt", "cohesion-free")]
    ncf_res = clean[("newton", "cohesion-free")]
    fm_full = fmax_of(full_res)
    rg = ridge_at(fm_full) if math.isfinite(fm_full) else None
    pc, pp = full_res.parameters["cohesion"], full_res.parameters["friction_angle"]
    txt = (
        f"**What the three points determine.** IPOPT, full model: status `{full_res.status}`, F_max = "
        f"{fm_full / 1e3:.5g} kN, K = {k_of(full_res):.5g} m, RMSE {full_res.rmse / 1e3:.3g} kN. "
    )
    if rg is not None:
        txt += (
            "At this F_max the ridge A c + W tan(phi) = F_max inside the bounds runs from "
            f"c = {rg[0][0] / 1e3:.3g} kPa "
            f"(phi = {math.degrees(rg[1][1]):.4g} deg) to c = {rg[0][1] / 1e3:.3g} kPa (phi = "
            f"{math.degrees(rg[1][0]):.4g} deg); every point of it fits equally well. "
        )
    if pc.ci95[0] is not None and pp.ci95[0] is not None:
        txt += (
            f"The library's ranges, which also let F_max vary within its 95 % interval (Student t with "
            f"{full_res.dof} residual degree(s) of freedom), are c {pc.ci95[0] / 1e3:.3g}-{pc.ci95[1] / 1e3:.3g} kPa "
            f"and phi {math.degrees(pp.ci95[0]):.3g}-{math.degrees(pp.ci95[1]):.3g} deg. "
        )
    txt += (
        f"The bounded cohesion-free fit (IPOPT) ends with phi = {math.degrees(cf_res.theta[1]):.4g} deg"
        f"{' ON ITS UPPER BOUND' if cf_res.active_bounds.get('friction_angle') == 'upper' else ''}, "
        f"RMSE {cf_res.rmse / 1e3:.3g} kN; the unbounded cohesion-free Newton/Gauss-Newton fit gives "
        f"phi = {math.degrees(ncf_res.theta[1]):.4g} deg, K = {k_of(ncf_res):.5g} m, RMSE {ncf_res.rmse / 1e3:.3g} kN "
        f"(status `{ncf_res.status}`). With c = 0 these data want phi = "
        f"{math.degrees(math.atan(fm_full / HEAVY.weight)):.4g} deg, above the seed's bound of "
        f"{math.degrees(PRACTICAL_BOUNDS.friction_angle[1]):g} deg."
    )
    L.append(txt)
    L.append("")
    L.append("Library statement for the IPOPT full-model fit:")
    L.append("")
    L.append("```")
    L.append(full_res.report())
    L.append("```")
    L.append("")

    # ---- Table 2
    L.append(f"## Table 2 - +-3 % uniform white noise on F and i, {args.draws} draws")
    L.append("")
    L.append(
        "Each draw multiplies every F and every i by an independent (1 + u), u ~ U(-0.03, 0.03), and is fitted "
        "with `fit_many` (Newton started from the Table 1 vector). Distributions over successful fits: "
        "median [5 %, 95 % percentiles]. F_max and K errors are relative to the noise-free fit of the same "
        "method and model (Table 1; the IPOPT fit where the method fails), so they measure the noise alone; "
        "'vs actual' uses the seed's actual values with l = 2.8 m. 'On a bound' counts fits with a free "
        "parameter on a bound (for the full model that is the arbitrary ridge point, and means nothing)."
    )
    L.append("")
    L.append(
        "| method / model | success | F_max error (%) | K error (%) | F_max error vs actual (%) | "
        "K error vs actual (%) | solver's c (kPa) | solver's phi (deg) | on a bound | wall (s) |"
    )
    L.append("|---|---|---|---|---|---|---|---|---|---|")
    for (method, model), r in noise.items():
        cphi = "(fixed 0)" if model == "cohesion-free" else dist(r["c"])
        L.append(
            f"| {method} / {model} | {r['success']}/{r['n']} ({100 * r['success'] / r['n']:.1f} %) | "
            f"{dist(r['fm_err'], '+.2f')} | {dist(r['K_err'], '+.2f')} | {dist(r['fm_err_act'], '+.2f')} | "
            f"{dist(r['K_err_act'], '+.2f')} | {cphi} | {dist(r['phi'], '.3g')} | {r['on_bound']} | "
            f"{r['wall']:.2f} |"
        )
    L.append("")
    L.append(
        "Statuses: "
        + "; ".join(
            f"{m}/{mo}: " + ", ".join(f"{k} x{v}" for k, v in r["statuses"].items()) for (m, mo), r in noise.items()
        )
    )
    L.append("")
    rcf, rncf = noise[("ipopt", "cohesion-free")], noise[("newton", "cohesion-free")]
    L.append(
        f"Bounded cohesion-free fits that ended on a bound: {rcf['on_bound']} of {rcf['success']}. Where phi sits on "
        f"its upper bound ({math.degrees(PRACTICAL_BOUNDS.friction_angle[1]):g} deg), F_max = W tan(phi) is set "
        "by the bound, not by the data, so a narrow F_max spread there is not precision. The unbounded "
        f"cohesion-free row (Newton/Gauss-Newton, {rncf['success']}/{rncf['n']} succeeded) shows the effect of "
        f"the noise alone: F_max error {dist(rncf['fm_err'], '+.2f')} %, K error {dist(rncf['K_err'], '+.2f')} % "
        "(median [5 %, 95 %])."
    )
    L.append("")
    rf = noise[("ipopt", "full")]
    L.append(
        f"The seed reports one draw (*seed* Table 2: c {SEED_TABLE2['c']} %, phi {SEED_TABLE2['phi']} %, "
        f"K {SEED_TABLE2['K']} %). Over {args.draws} draws the |error| vs the actual values of the solver's "
        f"c (full model, IPOPT) has median {np.median(rf['c_err_act']):.3g} % [5-95 %: {q(rf['c_err_act'], 5):.3g}, "
        f"{q(rf['c_err_act'], 95):.3g}], of phi {np.median(rf['phi_err_act']):.3g} % "
        f"[{q(rf['phi_err_act'], 5):.3g}, {q(rf['phi_err_act'], 95):.3g}], of K "
        f"{np.median(rf['K_abs_err_act']):.3g} % [{q(rf['K_abs_err_act'], 5):.3g}, {q(rf['K_abs_err_act'], 95):.3g}]. "
        f"In {rf['cphi_identifiable']} of {rf['success']} successful full-model fits did the library call c "
        "identifiable: the spread of c and phi is motion along the ridge, not an estimation error; F_max and "
        "K are what the noisy data determine (columns 3-4)."
    )
    L.append("")
    L.append("![noise](table2_noise.png)")
    L.append("")

    # ---- Robustness
    L.append(f"## Robustness - {args.starts} random initial vectors in [0, 89]")
    L.append("")
    L.append(
        "The seed's vector p0 = [c, phi, K] has 'random positive values in the range [0, 89]' in the units of its "
        "Table 1. Interpretation used: c0 in kPa and phi0 in degrees (uniform in [0, 89]); for K0 the literal "
        "reading (metres, [0, 89] m) and, as a second run, millimetres ([0, 0.089] m, which covers the practical "
        "range 0.006-0.05 m). The same random numbers are used for both. IPOPT clips starts to the bounds. "
        "'Converged' = the library reports success and finite numbers."
    )
    L.append("")
    L.append(
        "| K0 unit | method / model | converged | refused | final F_max (kN) | final K (m) | final c (kPa) | "
        "final phi (deg) | RMSE (kN) | statuses |"
    )
    L.append("|---|---|---|---|---|---|---|---|---|---|")
    for (k_unit, method, model), r in rob.items():
        L.append(
            f"| {k_unit} | {method} / {model} | {r['converged']}/{r['n']} | {r['refused']} | "
            f"{dist(r['fm'] / 1e3, '.5g')} | {dist(r['K'], '.4g')} | "
            f"{'(fixed 0)' if model == 'cohesion-free' else dist(r['c'], '.3g')} | {dist(r['phi'], '.4g')} | "
            f"{dist(r['rmse'] / 1e3, '.3g')} | " + ", ".join(f"{k} x{v}" for k, v in r["statuses"].items()) + " |"
        )
    L.append("")
    rn = rob[("m", "newton", "full")]
    ri = rob[("m", "ipopt", "full")]
    L.append(
        f"The seed: all 100 starts 'converged to the true values'. Here the Newton method converges for "
        f"{rn['converged']}/{rn['n']} (K0 in m) and {rob[('mm', 'newton', 'full')]['converged']}/{rn['n']} "
        f"(K0 in mm) starts; IPOPT (full) for {ri['converged']}/{ri['n']} and "
        f"{rob[('mm', 'ipopt', 'full')]['converged']}/{ri['n']}. Among converged IPOPT full-model fits the final "
        f"c spans {fmt(q(ri['c'], 0), '.3g')}-{fmt(q(ri['c'], 100), '.3g')} kPa and phi "
        f"{fmt(q(ri['phi'], 0), '.4g')}-{fmt(q(ri['phi'], 100), '.4g')} deg while F_max spans "
        f"{fmt(q(ri['fm'], 0) / 1e3, '.6g')}-{fmt(q(ri['fm'], 100) / 1e3, '.6g')} kN and K "
        f"{fmt(q(ri['K'], 0), '.5g')}-{fmt(q(ri['K'], 100), '.5g')} m: the identifiable F_max and K come out the "
        "same from every start. " + ridge_point_text(ri, fm_full) + " "
        f"The seed's own method on the identifiable model (Newton/Gauss-Newton, cohesion-free) converges for "
        f"{rob[('m', 'newton', 'cohesion-free')]['converged']}/{rn['n']} (K0 in m) and "
        f"{rob[('mm', 'newton', 'cohesion-free')]['converged']}/{rn['n']} (K0 in mm) starts."
    )
    L.append("")
    L.append("![robustness](robustness.png)")
    L.append("")

    # ---- Figures 2-6
    L.append("## Figures 2-6")
    L.append("")
    for r in t1:
        if r["res"].success and theta_finite(r["res"]):
            e = pct(r["res"].residuals + WONG_FORCE, WONG_FORCE)
            L.append(
                f"- Fig. 2, {row_label(r)}: back-predicted errors "
                f"{e.min():+.2f} % to {e.max():+.2f} % (*seed*: {SEED_FIG2[0]:+.1f} % to {SEED_FIG2[1]:+.1f} %)."
            )
    L.append(f"- Seed's 'actual' values (no fit, l = 2.8 m): {e_act.min():+.2f} % to {e_act.max():+.2f} %.")
    L.append("")
    L.append("![Fig. 2](fig2_backprediction.png)")
    L.append("")
    # Figs 3-4 numbers
    i0 = 0.07
    Sh = normalised_sensitivities(HEAVY, SEED_ACTUAL, np.array([i0]))[0]
    Sl = normalised_sensitivities(LIGHT, SEED_ACTUAL, np.array([i0]))[0]
    fmh, fml = max_thrust(SEED_ACTUAL, HEAVY), max_thrust(SEED_ACTUAL, LIGHT)
    L.append(
        f"Figs. 3-4 (soil: seed's actual values). Normalised sensitivities (p/F) dF/dp at i = {i0}: heavy "
        f"vehicle c {Sh[0]:.4f}, phi {Sh[1]:.3f}, K {Sh[2]:+.3f}; light vehicle c {Sl[0]:.4f}, phi {Sl[1]:.3f}, "
        f"K {Sl[2]:+.3f}. Cohesion's share of F_max, A c / (A c + W tan phi): heavy "
        f"{A * SEED_ACTUAL.cohesion / fmh * 100:.2f} % (A = {A:g} m^2), light "
        f"{LIGHT.contact_area * SEED_ACTUAL.cohesion / fml * 100:.1f} % (A = {LIGHT.contact_area:g} m^2). "
        "The seed's qualitative finding holds: cohesion is negligible for the heavy vehicle and not for the "
        "light one - but 'insensitive' is not the reason c cannot be identified (see below): even for the "
        "light vehicle, c and phi are inseparable at one normal load."
    )
    L.append("")
    L.append("![Fig. 3](fig3_sensitivity_heavy.png)")
    L.append("")
    L.append("![Fig. 4](fig4_cohesion_heavy_vs_light.png)")
    L.append("")
    for r in t1:
        if r["method"] == "ipopt" and r["start"] == "default":
            e = pct(r["res"].residuals + WONG_FORCE, WONG_FORCE)
            L.append(
                f"- Fig. 6, {r['model']} model (IPOPT): {e.min():+.2f} % to {e.max():+.2f} %, RMSE "
                f"{r['res'].rmse / 1e3:.3g} kN (*seed*: {SEED_FIG6[r['model']][0]:+.1f} % to "
                f"{SEED_FIG6[r['model']][1]:+.1f} %)."
            )
    L.append(
        "- Unbounded cohesion-free fit (Newton/Gauss-Newton on Eq. 8): errors "
        + ", ".join(f"{v:+.2f} %" for v in pct(ncf_res.residuals + WONG_FORCE, WONG_FORCE))
        + f", RMSE {ncf_res.rmse / 1e3:.3g} kN - the full model's RMSE is {full_res.rmse / 1e3:.3g} kN: without the "
        f"phi bound, dropping c costs nothing (the full model's extra parameter only moves along the ridge). "
        f"F_max: full {fm_full / 1e3:.5g} kN, cohesion-free bounded {fmax_of(cf_res) / 1e3:.5g} kN, unbounded "
        f"{fmax_of(ncf_res) / 1e3:.5g} kN; K {k_of(full_res):.5g}, {k_of(cf_res):.5g}, {k_of(ncf_res):.5g} m."
    )
    L.append("")
    L.append("![Fig. 5](fig5_models_vs_data.png)")
    L.append("")
    L.append("![Fig. 6](fig6_model_errors.png)")
    L.append("")

    # ---- Fig. 7
    L.append("## Fig. 7 - traversability, as the seed draws it and as it should be read")
    L.append("")
    L.append(
        f"Heavy vehicle W = {W / 1e3:.0f} kN, A = {A:g} m^2 (ASSUMED), mu_r = {HEAVY.rolling_resistance}; "
        f"drivetrain capability {DRIVETRAIN_MAX / 1e3:.0f} kN (the seed's UGV); soil thrust counted up to an "
        f"acceptable slip of {ACCEPTABLE_SLIP:.2f} (our choice); on a slope theta the normal load is W cos(theta) "
        "and the resistance W (mu_r cos(theta) + sin(theta)). K: dry sand "
        f"{TERRAINS['dry_sand'].shear_modulus} m, clayey soil {TERRAINS['clayey_soil'].shear_modulus} m "
        "(typical values, not from the source). Bekker compaction resistance R_c is shown as a check "
        "(mu_r is already meant to include motion resistance)."
    )
    L.append("")
    L.append(
        "| terrain | ground | seed's 'required' A c + W tan(phi) (kN) | seed's verdict for 120 kN | soil thrust "
        f"at i = {ACCEPTABLE_SLIP:.2f} (kN) | available = min(120, soil) (kN) | resistance (kN) | margin (kN) | "
        "verdict | R_c Bekker (kN) | verdict with R_c |"
    )
    L.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in mrows:
        ground = "flat" if r["theta"] == 0 else f"{r['theta']:.0f} deg slope"
        L.append(
            f"| {r['name']} | {ground} | "
            f"{r['seed_required'] / 1e3:.1f} | {'crosses' if r['seed_verdict'] else 'does not cross'} | "
            f"{r['soil_thrust'] / 1e3:.1f} | {r['available'] / 1e3:.1f} | {r['resistance'] / 1e3:.1f} | "
            f"{r['margin'] / 1e3:+.1f} | {'GO' if r['go'] else 'NO-GO'} | {r['compaction'] / 1e3:.2f} | "
            f"{'GO' if r['go_with_rc'] else 'NO-GO'} |"
        )
    L.append("")
    ds = {r["theta"]: r for r in mrows if r["key"] == "dry_sand"}
    cl = {r["theta"]: r for r in mrows if r["key"] == "clayey_soil"}
    L.append(
        f"The seed's figure plots the soil's own thrust limit A c + W tan(phi) (dry sand "
        f"{ds[0]['seed_required'] / 1e3:.1f} kN, clay {cl[0]['seed_required'] / 1e3:.1f} kN) and reads it as the "
        "force 'required' to traverse, concluding that a 120 kN UGV crosses clay but not dry sand. A vehicle is "
        "stopped when the thrust it can get - the smaller of its drivetrain's and the soil's - falls below the "
        f"resistance. On flat ground the resistance is {ds[0]['resistance'] / 1e3:.1f} kN and the vehicle crosses "
        f"both ({'GO' if ds[0]['go'] else 'NO-GO'} / {'GO' if cl[0]['go'] else 'NO-GO'}); on a {SLOPE_DEG:.0f} deg "
        f"slope ({ds[SLOPE_DEG]['resistance'] / 1e3:.1f} kN required) it crosses dry sand (available "
        f"{ds[SLOPE_DEG]['available'] / 1e3:.1f} kN, {'GO' if ds[SLOPE_DEG]['go'] else 'NO-GO'}) and not clay "
        f"(available {cl[SLOPE_DEG]['available'] / 1e3:.1f} kN, {'GO' if cl[SLOPE_DEG]['go'] else 'NO-GO'}): the "
        "opposite of the seed's reading - the soil with the larger thrust limit is the easier one."
    )
    L.append("")
    L.append("![Fig. 7](fig7_traversability.png)")
    L.append("")

    # ---- agreement section
    L.append("## Where this library agrees with the seed and where it does not")
    L.append("")
    L.append("Agrees:")
    L.append("")
    L.append(
        f"- Cohesion has a negligible effect on the heavy vehicle's thrust (A c / F_max = "
        f"{A * SEED_ACTUAL.cohesion / fmh * 100:.2f} %) and a noticeable one on the light vehicle's "
        f"({LIGHT.contact_area * SEED_ACTUAL.cohesion / fml * 100:.1f} %)."
    )
    e_full = pct(full_res.residuals + WONG_FORCE, WONG_FORCE)
    e_cf = pct(cf_res.residuals + WONG_FORCE, WONG_FORCE)
    e_ncf = pct(ncf_res.residuals + WONG_FORCE, WONG_FORCE)
    L.append(
        f"- Without bounds the cohesion-free model (Eq. 8) fits Wong's points exactly as well as the full model "
        f"(RMSE {ncf_res.rmse / 1e3:.3g} vs {full_res.rmse / 1e3:.3g} kN; "
        f"errors {e_ncf.min():+.2f}..{e_ncf.max():+.2f} % "
        f"vs {e_full.min():+.2f}..{e_full.max():+.2f} %). With the seed's bound phi <= 40 deg it is worse "
        f"(RMSE {cf_res.rmse / 1e3:.3g} kN, errors {e_cf.min():+.2f}..{e_cf.max():+.2f} %), because the data want "
        f"phi = {math.degrees(math.atan(fm_full / W)):.4g} deg at c = 0."
    )
    L.append(
        f"- Partly: the seed's 'actual' values against what the data determine: F_max = {fm_full / 1e3:.5g} kN "
        f"(actual: {fm_act / 1e3:.5g} kN, {pct(fm_full, fm_act):+.1f} %), K = {k_of(full_res):.4g} m (actual 0.018 m, "
        f"{pct(k_of(full_res), 0.018):+.0f} %) with l = 2.8 m assumed - "
        f"K/l = {k_of(full_res) / HEAVY.track_length:.4g} "
        "is what the data fix, so K scales with the unknown l."
    )
    L.append("")
    L.append("Does not agree:")
    L.append("")
    ident = full_res.identifiability
    L.append(
        f"- **c and phi are not separable at one normal load.** At the seed's actual values the Jacobian columns "
        f"for c and phi have correlation {jc_act['corr']:.15f}, column-scaled singular values "
        + ", ".join(f"{s:.3g}" for s in jc_act["s_scaled"])
        + f". The library's IPOPT full-model fit reports rank {ident['rank']} of {ident['n_parameters']} and "
        "marks c and phi not identifiable"
        + (
            f"; at its F_max the ridge inside the bounds spans c {rg[0][0] / 1e3:.3g}-{rg[0][1] / 1e3:.3g} kPa "
            f"(phi {math.degrees(rg[1][1]):.4g}-{math.degrees(rg[1][0]):.4g} deg)"
            if rg is not None
            else ""
        )
        + ". The seed's Table 1 c values (0.65 and 16.48 kPa) and the 18.18 % 'error' are artefacts: the "
        "initial guess, and another ridge point. The same holds for the light vehicle: the proportionality "
        "dF/dphi = (W sec^2(phi) / A) dF/dc does not depend on W or A."
    )
    L.append(
        f"- **Newton's Jacobian is singular** (condition number {jc0['cond']:.3g} at the seed's start; library "
        f"status `{nres.status}`). The seed's 'ability to handle parameters individually' is the inability to "
        "move c."
    )
    L.append(
        "- **The seed's actual values do not reproduce the data.** Residuals at l = 2.8 m: "
        + ", ".join(f"{v:+.2f} %" for v in scan["e_28"])
        + f" (max |.| {scan['worst_28']:.2f} %). Scanning l "
        f"from {scan['grid'][0]:g} to {scan['grid'][-1]:g} m (b = 0.5 m, A = 2 b l) the best is l = "
        f"{scan['l_best']:.3f} m with max |residual| {scan['worst_best']:.2f} % ("
        + ", ".join(f"{v:+.2f}" for v in scan["e_best"])
        + " %): no l reproduces all three points within better "
        "than that. A reproduction must report residuals, not claim exact recovery."
    )
    n_cf_bound = noise[("ipopt", "cohesion-free")]["on_bound"]
    phi_ncf = noise[("newton", "cohesion-free")]["phi"]
    n_above = int(np.sum(phi_ncf > math.degrees(PRACTICAL_BOUNDS.friction_angle[1])))
    L.append(
        f"- **phi bound.** The seed's practical range ends at phi = "
        f"{math.degrees(PRACTICAL_BOUNDS.friction_angle[1]):g} deg while its actual phi is "
        f"{SEED_ACTUAL.friction_angle_deg:.1f} deg: the 'true' point lies outside the seed's own bounds. Wong's "
        f"points want phi = {math.degrees(math.atan(fm_full / W)):.4g} deg at c = 0; in {n_above} of "
        f"{phi_ncf.size} noisy draws the unbounded cohesion-free fit puts phi above "
        f"{math.degrees(PRACTICAL_BOUNDS.friction_angle[1]):g} deg, and {n_cf_bound} of "
        f"{noise[('ipopt', 'cohesion-free')]['success']} bounded cohesion-free fits end on the bound (reported "
        "as such). (On the full model the bound flags concern the arbitrary ridge point and mean nothing.)"
    )
    ls_res = clean[("least-squares", "full")]
    L.append(
        f"- **Robustness.** The seed's 100/100 is not reproducible as a statement about c and phi: its Newton "
        f"method converged {rn['converged']}/{rn['n']} (K0 in m) on the full model. The reported c depends on the "
        f"algorithm (and for some algorithms on the start), not on the data: IPOPT "
        f"{fmt(q(ri['c'], 0), '.3g')}-{fmt(q(ri['c'], 100), '.3g')} kPa over {ri['converged']} starts, least "
        f"squares (LM) {ls_res.theta[0] / 1e3:.3g} kPa from the Table 1 start, the vectorised batch engine of "
        f"`fit_many` median {np.median(rf['c']):.3g} kPa on the noisy draws - while F_max and K are the same for "
        "every start on the same data."
    )
    L.append(
        f"- **Fig. 7 misreading.** The seed's 'required' forces ({ds[0]['seed_required'] / 1e3:.1f} / "
        f"{cl[0]['seed_required'] / 1e3:.1f} kN) are soil thrust limits. With resistance on the right side "
        f"of the inequality the 120 kN vehicle crosses both on flat ground and, on {SLOPE_DEG:.0f} deg, dry sand "
        f"(margin {ds[SLOPE_DEG]['margin'] / 1e3:+.1f} kN) but not clay ({cl[SLOPE_DEG]['margin'] / 1e3:+.1f} kN)."
    )
    parts = [f"{row_label(r)}: {r['solve_med'] * 1e3:.3g} ms (`{r['res'].status}`)" for r in t1]
    L.append(
        f"- **Speed.** The seed: Newton {SEED_TABLE1['newton']['time']} s vs least squares "
        f"{SEED_TABLE1['least-squares']['time']} s ('about 10 times faster'). Here, median solve times on this "
        "machine: " + "; ".join(parts) + ". Newton on the full model is fast only because it stops at its first "
        "(singular) step. See benchmarks/ for timings against scipy."
    )
    L.append("")
    L.append(f"Run time: {time.perf_counter() - t_start:.1f} s.")
    L.append("")
    with open(P("report.md"), "w", encoding="utf-8") as fh:
        fh.write("\n".join(L))
    log(f"wrote {P('report.md')} in {time.perf_counter() - t_start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
