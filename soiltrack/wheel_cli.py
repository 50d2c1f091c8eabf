"""The rigid wheel on the command line: ``fit``, ``diagnose`` and ``simulate --kind sweep`` with a wheel JSON.

The subcommands hand over here when ``--vehicle`` names a ``{"running_gear": "rigid_wheel", ...}``
file; every option that does not apply to a wheel is refused (nothing is silently ignored).
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from .cliutil import EXIT_OK, EXIT_SOLVER, floats_arg, output_path
from .identify.outcome import exit_code
from .columns_cli import column_notes, columns_arg, with_column_notes
from .soilmodel import DataError
from .soilmodel.rigid_wheel import RigidWheel
from .soilmodel.wheel_sweep import WHEEL_KNOWN_COLUMNS

__all__ = ["fit_wheel_command", "diagnose_wheel_command", "simulate_wheel_command", "wheel_fixed_arg"]

# edge unit -> SI factor of the parameters --fix may hold
_FIX_UNITS = {
    "cohesion_kpa": ("cohesion", 1e3),
    "friction_angle_deg": ("friction_angle", math.pi / 180.0),
    "shear_modulus_m": ("shear_modulus", 1.0),
    "bekker_kc": ("bekker_kc", 1e3),
    "bekker_kphi": ("bekker_kphi", 1e3),
    "bekker_n": ("bekker_n", 1.0),
}


def wheel_fixed_arg(specs: list[str] | None, model: str) -> dict[str, float]:
    """``--fix NAME=VALUE`` (edge units) and ``--model cohesion-free`` -> ``{parameter: SI value}``."""
    out: dict[str, float] = {"cohesion": 0.0} if model == "cohesion-free" else {}
    for spec in specs or []:
        name, sep, val = spec.partition("=")
        name = name.strip()
        if not sep or name not in _FIX_UNITS:
            raise DataError(
                f"--fix expects NAME=VALUE with NAME one of {sorted(_FIX_UNITS)} (edge units: kPa, deg, m, "
                f"kN/m^(n+1), kN/m^(n+2), -), got {spec!r}"
            )
        (v,) = floats_arg(val, f"--fix {name}")
        key, fac = _FIX_UNITS[name]
        out[key] = v * fac
    return out


def _refuse(a: argparse.Namespace, allowed: set[str], defaults: dict, what: str) -> None:
    for opt, default in defaults.items():
        if opt in allowed:
            continue
        if getattr(a, opt, default) != default:
            raise DataError(f"--{opt.replace('_', '-')} does not apply to a rigid wheel ({what})")


def _effects(a: argparse.Namespace, wheel_only: bool = True) -> tuple[str, ...]:
    """The ``--effect`` names; ``wheel_only``: refused unless an effect of the rigid-wheel model (False: a joint
    fit with a tracked vehicle's file, which refuses effects itself, naming the file)."""
    from .identify.wheel.fitting import WHEEL_EFFECTS

    names = tuple(e.strip() for item in (a.effect or []) for e in item.split(",") if e.strip())
    bad = [e for e in names if e not in WHEEL_EFFECTS] if wheel_only else []
    if bad:
        raise DataError(f"--effect {bad[0]!r} is not an effect of the rigid-wheel model; it has {list(WHEEL_EFFECTS)}")
    return names


def _settings(a: argparse.Namespace):
    """The wheel model's settings: the defaults, with ``--bulldozing-density`` as the soil's unit weight."""
    from .soilmodel import G
    from .soilmodel.wheel import DEFAULT_WHEEL_SETTINGS, WheelSettings

    rho = getattr(a, "bulldozing_density", None)
    if rho is None:
        return DEFAULT_WHEEL_SETTINGS
    if not (math.isfinite(rho) and 100.0 <= rho <= 5000.0):
        raise DataError(f"--bulldozing-density expects a soil bulk density in [100, 5000] kg/m^3, got {rho:g}")
    return WheelSettings(bulldozing_unit_weight=rho * G)


def fit_wheel_command(a: argparse.Namespace, wheel: RigidWheel) -> int:
    """``soiltrack fit DATA --vehicle WHEEL.json``: the rigid-wheel fit; exit 0 converged, 1 failed."""
    from .identify.wheel import WheelFitOptions, fit_wheel
    from .soilmodel.wheel_sweep import read_wheel_sweep

    _refuse(
        a,
        set(),
        {
            "engine": "auto",
            "sigma": None,
            "bias_correction": "none",
            "torque_hold": None,
            "slip_noise": None,
            "intervals": None,
            "interval_method": None,
            "bounds": "practical",
            "method": "ipopt",
            "resistance": None,
            "negative_kc": False,
            "inner_radius_m": None,
            "outer_radius_m": None,
        },
        "its fit is bounded IPOPT; its rolling resistance is in its normal stresses",
    )
    if a.plot:
        output_path(a.plot, "--plot", figure=True)
    cols = columns_arg(a)
    data = read_wheel_sweep(a.data, driving_only=a.driving_only, slip_angle=a.slip_angle, columns=cols)
    opts = WheelFitOptions(
        fixed=wheel_fixed_arg(getattr(a, "fix", None), a.model), effects=_effects(a), settings=_settings(a)
    )
    result = fit_wheel(data, wheel, opts)
    print(
        with_column_notes(
            result.to_json() if a.json else result.report(), column_notes(a.data, cols, WHEEL_KNOWN_COLUMNS), a.json
        )
    )
    if a.plot:
        from .wheel_plots import plot_wheel_fit

        print(f"wrote the figure to {plot_wheel_fit(data, result, a.plot)}", file=sys.stderr)
    return exit_code(result.fit_outcome)


def diagnose_wheel_command(a: argparse.Namespace, wheel: RigidWheel) -> int:
    """``soiltrack diagnose DATA --vehicle WHEEL.json``: the rigid wheel's gap diagnosis."""
    from .identify.wheel.diagnosis import diagnose_wheel
    from .identify.wheel import WheelFitOptions
    from .soilmodel.wheel_sweep import read_wheel_sweep

    _refuse(a, set(), {"torque_hold": None, "bounds": "auto"}, "its soil bounds are the practical ranges")
    cols = columns_arg(a)
    data = read_wheel_sweep(a.data, driving_only=a.driving_only, slip_angle=a.slip_angle, columns=cols)
    cands = None
    if a.candidates is not None:
        cands = tuple(c.strip() for c in a.candidates.split(",") if c.strip())
    d = diagnose_wheel(
        data, wheel, WheelFitOptions(fixed=wheel_fixed_arg(getattr(a, "fix", None), a.model)), candidates=cands
    )
    print(
        with_column_notes(
            d.to_json() if a.json else d.report(), column_notes(a.data, cols, WHEEL_KNOWN_COLUMNS), a.json
        )
    )
    if a.plot:
        from .wheel_plots import plot_wheel_fit

        print(f"wrote the figure to {plot_wheel_fit(data, d.nominal, a.plot)}", file=sys.stderr)
    return EXIT_OK if d.converged else EXIT_SOLVER


def simulate_wheel_command(a: argparse.Namespace, wheel: RigidWheel, soil) -> int:
    """``soiltrack simulate --kind sweep --vehicle WHEEL.json``: a wheel rig sweep with its sinkage."""
    from .soilmodel import Soil
    from .soilmodel.wheel_simulation import DEFAULT_WHEEL_NOISE, simulate_wheel_sweep
    from .soilmodel.wheel_sweep import write_wheel_sweep

    if a.plot:
        raise DataError("--plot is not available for simulated wheel sweeps; fit them with --plot")
    if a.kind != "sweep":
        raise DataError("a rigid wheel on a rig makes sweeps only: use --kind sweep")
    if a.model != "full":
        raise DataError("--model does not apply to simulating a rigid wheel (give the soil's cohesion instead)")
    slip_sinkage = 0.0
    for spec in a.effect or []:
        name, _, val = spec.partition("=")
        if name.strip() != "slip_sinkage":
            raise DataError(f"--effect {spec!r}: the rigid-wheel model has only slip_sinkage=VALUE")
        (slip_sinkage,) = floats_arg(val, "--effect slip_sinkage")
    if getattr(a, "bekker", None):
        vals = floats_arg(a.bekker, "--bekker")
        if len(vals) != 3:
            raise DataError(f"--bekker expects KC,KPHI,N (kN/m^(n+1), kN/m^(n+2), -), got {a.bekker!r}")
        kc, kphi, n = vals
        soil = Soil(
            cohesion=soil.cohesion,
            friction_angle=soil.friction_angle,
            shear_modulus=soil.shear_modulus,
            name=soil.name,
            n=n,
            k_c=kc * 1e3,
            k_phi=kphi * 1e3,
        )
    kw: dict[str, Any] = {}
    if a.slips:
        kw["slips"] = floats_arg(a.slips, "--slips")
    loads = floats_arg(a.loads, "--loads") if a.loads else None
    if loads is None:
        raise DataError("a rigid wheel has no mass: give its normal load(s) with --loads (N)")
    data = simulate_wheel_sweep(
        wheel,
        soil,
        normal_loads=loads,
        noise=None if a.noise == "none" else DEFAULT_WHEEL_NOISE,
        seed=a.seed,
        slip_sinkage=slip_sinkage,
        **kw,
    )
    if a.output == "-":
        write_wheel_sweep(data, sys.stdout)
    else:
        try:
            write_wheel_sweep(data, a.output)
        except OSError as e:
            raise DataError(f"cannot write the CSV: {e.strerror or e}", file=a.output) from None
        print(f"wrote {data.n_samples} rows (wheel sweep) to {a.output}", file=sys.stderr)
    return EXIT_OK


#: Public names of the wheel options' parsers (the joint fit of several files uses them).
wheel_effects_arg = _effects
wheel_settings_arg = _settings
