"""Figure of a bevameter test and its fit: readings per pressure or plate width, fitted curves."""

from __future__ import annotations

import numpy as np

from .identify.estimates.estimate import Estimate
from .plots import plt, save_figure
from .soilmodel import PlateTest, ShearTest, plate_pressure, shear_stress

__all__ = ["plot_soil_test"]


def _si(fit: Estimate, key: str) -> float:
    """A fitted parameter's SI value (the curves are drawn only from identifiable ones)."""
    v = fit.parameters[key].value
    if v is None:
        raise ValueError(f"{key} was not estimated: no curve from it")
    return float(v)


def _combination_si(fit: Estimate, key: str, factor: float) -> float:
    """An identified combination's value (edge units) times ``factor`` (to SI)."""
    v = fit.combinations[key].value
    if v is None:
        raise ValueError(f"{key} was not estimated: no curve from it")
    return float(v) * factor


def _curves(test: ShearTest | PlateTest, fit: Estimate):
    """``(levels, x readings, y readings, x grid, fitted y per level)`` in kPa / mm."""
    P = fit.parameters
    if isinstance(test, ShearTest):
        lev, x, y = test.normal_pressure, test.shear_displacement, test.shear_stress
        grid = np.linspace(0.0, float(x.max()), 200)
        K = _si(fit, "shear_modulus_m")
        out = []
        for s in np.unique(lev):
            if P["cohesion_kpa"].identifiable:
                tau = shear_stress(grid, s, _si(fit, "cohesion_kpa"), _si(fit, "friction_angle_deg"), K)
            else:
                tau = shear_stress(grid, 0.0, _combination_si(fit, "shear_strength_kpa", 1e3), 0.0, K)
            out.append(tau)
        return lev, x, y, grid, out
    lev, x, y = test.plate_width, test.sinkage, test.pressure
    grid = np.linspace(0.0, float(x.max()), 200)
    n = _si(fit, "bekker_n")
    out = []
    for b in np.unique(lev):
        if P["bekker_kc"].identifiable:
            p = plate_pressure(grid, b, _si(fit, "bekker_kc"), _si(fit, "bekker_kphi"), n)
        else:
            p = plate_pressure(grid, 1.0, 0.0, _combination_si(fit, "bekker_k_eq", 1e3), n)
        out.append(p)
    return lev, x, y, grid, out


def plot_soil_test(test: ShearTest | PlateTest, fit: Estimate, path: str) -> str:
    """Save the readings and the fitted curve of each normal pressure (shear) or plate width (plate)."""
    shear = isinstance(test, ShearTest)
    lev, x, y, grid, curves = _curves(test, fit)
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    cmap = plt.get_cmap("viridis")
    levels = np.unique(lev)
    for k, (v, curve) in enumerate(zip(levels, curves)):
        col = cmap(k / max(len(levels) - 1, 1) * 0.9)
        sel = lev == v
        label = f"sigma = {v / 1e3:.3g} kPa" if shear else f"b = {v * 1e3:.3g} mm"
        ax.plot(x[sel] * 1e3, y[sel] / 1e3, "o", ms=3.5, color=col, label=label)
        ax.plot(grid * 1e3, curve / 1e3, "-", color=col, lw=1.6)
    ax.set_xlabel("shear displacement j (mm)" if shear else "sinkage z (mm)")
    ax.set_ylabel("shear stress tau (kPa)" if shear else "pressure p (kPa)")
    status = "converged" if fit.converged else "NOT converged"
    what = "shear test: tau = (c + sigma tan phi)(1 - exp(-j/K))" if shear else "plate test: p = (k_c/b + k_phi) z^n"
    ax.set_title(f"{what}\nIPOPT {status}; points: readings, lines: fit", fontsize=9)
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)
