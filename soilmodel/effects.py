"""Unmodelled physical effects (DESIGN.md section 6) as switchable augmentations of the model.

Each effect is a named augmentation of the nominal model (Eqs. 1-4) with its own named
parameters. The nominal model is exactly the effect-off case: an effect that is absent from
an :class:`EffectSet` leaves the nominal expressions untouched, and an effect that is present
with its parameters at their ``off_value`` gives the same numbers, bit for bit (every
augmentation is written as ``nominal + parameter * term`` or ``nominal * (1 + parameter)`` or
``nominal * cos(parameter)`` with a finite ``term``).

The effects and their parameters (``primary`` is what the CLI shorthand ``--effect NAME=VALUE``
sets):

``grade`` (``theta_rad``, rad)
    Constant slope, positive uphill. Normal load ``W cos(theta)`` (in the thrust and in the
    rolling resistance) and an extra resistance ``W sin(theta)``. Any other constant extra
    resistance (e.g. Bekker compaction) looks the same in a drive log.
``speed_resistance`` (``mu_v``, s/m)
    Motion resistance growing with speed: ``N (mu_r + mu_v v)``.
``slip_sinkage`` (``mu_s``, -)
    Slip-induced sinkage: ``N (mu_r + mu_s |i|)`` (``|i|``: a skidding track digs in too).
``drivetrain_friction`` (``tau_c``, N m, primary; ``tau_v``, N m s/rad)
    Torque lost between the torque sensor and the track: ``tau_c sgn(w) + tau_v w``.
``radius_error`` (``eps``, -)
    The track's effective radius ``r (1 + eps)`` replaces the sprocket radius in the slip and
    in the torque arm. Slip computed with the nominal r is then offset by about ``-eps``.
``hump_shear`` (``drop``, -, primary; ``k_ratio``, -)
    Strain-softening soil whose shear stress peaks, then falls. See :func:`softening_shear`.
``pressure_distribution`` (``e``, -, primary; ``alpha``, -; ``n_w``, -)
    Non-uniform normal pressure ``p(x) = p_mean [1 + e (2x/l - 1) + alpha cos(2 pi n_w x / l)]``
    with x from the front of the contact (``e > 0``: load shifted to the rear).
``mass_error`` (``delta``, -)
    Actual mass ``m (1 + delta)``, and the weight with it.

Hump shear, the parametrisation
-------------------------------
Wong's type B form (DESIGN.md section 6),
``tau/tau_max = K_r {1 + [1/(K_r (1 - 1/e)) - 1] exp(1 - j/K_w)} (1 - exp(-j/K_w))``, does not
contain Janosi-Hanamoto as a special case (K_r = 1 still gives a hump of about 5 %), so it
cannot be an augmentation whose "off" value is the nominal model. The library uses the nested
strain-softening form::

    s(j) = (1 - exp(-j/K)) * [1 - drop * (1 - exp(-j/K_s))],   K_s = k_ratio * K

``drop = 0`` is Janosi-Hanamoto exactly; for ``0 < drop < 1`` and ``k_ratio > 1`` the shear
stress rises with modulus K, peaks, then falls to the residual fraction ``1 - drop`` of the
Mohr-Coulomb strength over the longer displacement scale K_s: the shape of type B (peak then
residual). Over the track this gives a closed form (``g(X) = 1 - (1 - exp(-X))/X``, the
Janosi-Hanamoto slip factor of :func:`~.traction.slip_factor`, ``X = |i| l / K``)::

    mean over the track of s = g(X) - drop * [g(X) + g(X / k_ratio) - g(X (1 + 1/k_ratio))]

:func:`wong_type_b_shear` gives Wong's form itself for comparison.

Pressure distribution, the closed form
--------------------------------------
With ``beta = |i| / K`` and ``X = beta l``, the mean over the track of the three pressure
shapes times ``1 - exp(-beta x)`` is ``g(X)`` (uniform), ``m1(X) = (1 - e^-X)/X -
2 (1 - e^-X (1 + X))/X^2`` (linear shift; series below X = 1) and
``mc(X) = -(1 - e^-X) X / (X^2 + (2 pi n_w)^2)`` (cosine, exact for integer ``n_w``). Hence::

    F = sign(i) [(A c + N tan(phi)) g(X) + N tan(phi) (e m1(X) + alpha mc(X))]

Cohesion is a property of the soil, not of the pressure, so only the friction part changes.
The cosine has ``n_w`` periods along the track: peaks at ``x = k l / n_w``, ``k = 0..n_w``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Iterable, Mapping

import casadi as ca
import numpy as np

from .errors import DataError
from .soil import Soil
from .traction import check_model, max_thrust_expr, slip_factor, thrust_expr
from .vehicle import Vehicle

__all__ = [
    "ParamSpec", "EffectSpec", "EFFECTS", "EffectSet", "parse_effects", "effect_symbols",
    "DEFAULT_STANDSTILL_SPEED", "smooth_sign", "effective_mass", "effective_weight", "effective_normal_load",
    "effective_radius", "motion_resistance", "torque_loss", "thrust_with_effects",
    "thrust_with_effects_function", "tractive_force_with_effects", "softening_shear", "wong_type_b_shear",
    "pressure_profile", "DEFAULT_RIG_SPEED", "SWEEP_MEASURES", "parameter_bounds", "parameter_scale",
    "effect_structure", "rig_true_slip", "sweep_measurement", "normal_load_function",
]

_INF = math.inf

#: Below this speed (m/s) Coulomb-like terms (rolling resistance, Coulomb drivetrain friction)
#: are regularised smoothly through zero; at and above it they are exactly the textbook terms.
DEFAULT_STANDSTILL_SPEED = 0.01


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of an effect.

    Parameters
    ----------
    name, unit, description
        Identifier (used in ``effect.param`` CLI strings), SI unit, meaning.
    off_value
        Value at which this parameter leaves the nominal model unchanged. For shape parameters
        that act only together with the effect's primary parameter (``k_ratio``, ``n_w``) it
        is their default.
    default
        Value used when the effect is on and the parameter not given; ``None`` means
        ``off_value`` (for ``n_w``: the vehicle's road wheels per side, else 5).
    lower, upper
        Physically admissible closed range.
    integer
        True for integer parameters (never identified, never symbolic).
    """

    name: str
    unit: str
    description: str
    off_value: float
    default: float | None = None
    lower: float = -_INF
    upper: float = _INF
    integer: bool = False


@dataclass(frozen=True)
class EffectSpec:
    """One unmodelled effect: its name, physics, parameters and CLI primary parameter.

    Attributes
    ----------
    name, description
        Contract name (DESIGN.md section 6) and physics in words.
    params
        Its parameters.
    primary
        The parameter set by the shorthand ``NAME=VALUE``.
    shows_in
        Kinds of data where the effect leaves a signature: ``"drive"`` and/or ``"sweep"``.
    """

    name: str
    description: str
    params: tuple[ParamSpec, ...]
    primary: str
    shows_in: tuple[str, ...] = ("drive", "sweep")

    def param(self, name: str) -> ParamSpec:
        """The :class:`ParamSpec` called ``name`` (DataError listing the valid ones if none)."""
        for p in self.params:
            if p.name == name:
                return p
        raise DataError(f"effect '{self.name}' has no parameter '{name}'; valid: "
                        f"{[p.name for p in self.params]}")

    @property
    def param_names(self) -> tuple[str, ...]:
        """Names of the parameters, in order."""
        return tuple(p.name for p in self.params)


#: Registry of the unmodelled effects of DESIGN.md section 6 (names are a public contract).
EFFECTS: dict[str, EffectSpec] = {
    "grade": EffectSpec(
        "grade", "unknown constant slope (or any constant extra motion resistance, e.g. Bekker compaction): "
        "normal load W cos(theta), extra resistance W sin(theta)",
        (ParamSpec("theta_rad", "rad", "slope angle, positive uphill", 0.0, lower=-1.2, upper=1.2),),
        "theta_rad"),
    "speed_resistance": EffectSpec(
        "speed_resistance", "motion resistance growing with speed: N (mu_r + mu_v v)",
        (ParamSpec("mu_v", "s/m", "speed coefficient of motion resistance", 0.0, lower=-1.0, upper=1.0),),
        "mu_v", ("drive", "sweep")),
    "slip_sinkage": EffectSpec(
        "slip_sinkage", "slip-induced sinkage: resistance N (mu_r + mu_s |i|)",
        (ParamSpec("mu_s", "-", "slip coefficient of motion resistance", 0.0, lower=-1.0, upper=2.0),),
        "mu_s"),
    "drivetrain_friction": EffectSpec(
        "drivetrain_friction", "torque lost between the torque sensor and the track: tau_c sgn(w) + tau_v w",
        (ParamSpec("tau_c", "N m", "Coulomb torque loss (both tracks)", 0.0, lower=-_INF, upper=_INF),
         ParamSpec("tau_v", "N m s/rad", "viscous torque loss coefficient (both tracks)", 0.0,
                   lower=-_INF, upper=_INF)),
        "tau_c", ("drive",)),
    "radius_error": EffectSpec(
        "radius_error", "effective track radius r (1 + eps) in the slip and in the torque arm",
        (ParamSpec("eps", "-", "relative error of the effective radius", 0.0, lower=-0.5, upper=0.5),),
        "eps"),
    "hump_shear": EffectSpec(
        "hump_shear", "strain-softening soil: s(j) = (1 - exp(-j/K)) [1 - drop (1 - exp(-j/(k_ratio K)))]; "
        "shear stress peaks, then falls to the residual fraction 1 - drop",
        (ParamSpec("drop", "-", "fraction of the Mohr-Coulomb strength lost at large shear displacement "
                   "(residual = 1 - drop); 0 = Janosi-Hanamoto", 0.0, lower=0.0, upper=0.95),
         ParamSpec("k_ratio", "-", "softening displacement modulus over K (K_s = k_ratio K); a hump needs "
                   "k_ratio > 1", 5.0, default=5.0, lower=0.05, upper=1000.0)),
        "drop", ("sweep", "drive")),
    "pressure_distribution": EffectSpec(
        "pressure_distribution", "non-uniform normal pressure p(x) = p_mean [1 + e (2x/l - 1) + "
        "alpha cos(2 pi n_w x / l)], x from the front",
        (ParamSpec("e", "-", "front/rear shift (e > 0: more load on the rear)", 0.0, lower=-1.0, upper=1.0),
         ParamSpec("alpha", "-", "amplitude of the road-wheel pressure peaks", 0.0, lower=-1.0, upper=1.0),
         ParamSpec("n_w", "-", "number of road-wheel periods along the track (default: the vehicle's "
                   "road wheels per side, else 5)", 5.0, default=None, lower=1.0, upper=50.0, integer=True)),
        "e", ("sweep", "drive")),
    "mass_error": EffectSpec(
        "mass_error", "actual mass (payload) differs from the nominal: m (1 + delta), and W with it",
        (ParamSpec("delta", "-", "relative mass error", 0.0, lower=-0.9, upper=10.0),),
        "delta"),
}

_ORDER = tuple(EFFECTS)


def _valid_names() -> str:
    return ", ".join(_ORDER)


def _spec(name: str) -> EffectSpec:
    try:
        return EFFECTS[name]
    except KeyError:
        raise DataError(f"unknown effect '{name}'; valid effects: {_valid_names()}") from None


def _check_value(spec: EffectSpec, p: ParamSpec, value: Any) -> float:
    if isinstance(value, bool):
        raise DataError(f"{spec.name}.{p.name} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise DataError(f"{spec.name}.{p.name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise DataError(f"{spec.name}.{p.name} must be finite, got {value!r}")
    if not p.lower <= v <= p.upper:
        raise DataError(f"{spec.name}.{p.name} = {v:g} is outside its admissible range "
                        f"[{p.lower:g}, {p.upper:g}] {p.unit}")
    if p.integer:
        if not v.is_integer():
            raise DataError(f"{spec.name}.{p.name} must be an integer, got {value!r}")
    return v


@dataclass(frozen=True)
class EffectSet:
    """An immutable, hashable set of switched-on effects with numeric parameter values.

    Build it with :func:`parse_effects`. ``entries`` holds ``(effect, ((param, value), ...))``
    in registry order, every parameter filled in (``None`` for ``n_w`` means "from the
    vehicle"). An empty set is the nominal model.
    """

    entries: tuple[tuple[str, tuple[tuple[str, float | None], ...]], ...] = ()

    def __contains__(self, name: object) -> bool:
        return any(name == n for n, _ in self.entries)

    def __iter__(self):
        return iter(self.names)

    def __len__(self) -> int:
        return len(self.entries)

    def __bool__(self) -> bool:
        return bool(self.entries)

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the effects that are on, in registry order."""
        return tuple(n for n, _ in self.entries)

    def params(self, name: str) -> dict[str, float | None]:
        """Parameter values of effect ``name`` (its off values when the effect is not on)."""
        spec = _spec(name)
        for n, ps in self.entries:
            if n == name:
                return dict(ps)
        return {p.name: p.off_value for p in spec.params}

    def value(self, name: str, param: str, vehicle: Vehicle | None = None) -> float:
        """One parameter value; ``n_w = None`` is resolved from ``vehicle`` (road wheels, else 5)."""
        spec = _spec(name)
        spec.param(param)
        v = self.params(name)[param]
        if v is None:
            return float(vehicle.road_wheels) if vehicle is not None and vehicle.road_wheels else 5.0
        return float(v)

    def to_dict(self) -> dict[str, dict[str, float | None]]:
        """``{effect: {param: value}}`` (the form :func:`parse_effects` accepts)."""
        return {n: dict(ps) for n, ps in self.entries}

    def without(self, *names: str) -> "EffectSet":
        """A copy with the named effects switched off."""
        for n in names:
            _spec(n)
        return EffectSet(tuple(e for e in self.entries if e[0] not in names))

    def __str__(self) -> str:
        if not self.entries:
            return "none"
        parts = []
        for n, ps in self.entries:
            inner = ", ".join(f"{k}={'vehicle' if v is None else format(v, 'g')}" for k, v in ps)
            parts.append(f"{n}({inner})")
        return "; ".join(parts)


def _split_cli(items: Iterable[str]) -> list[tuple[str, str | None, str | None]]:
    out = []
    for raw in items:
        if not isinstance(raw, str):
            raise DataError(f"effect specification must be a string like 'grade=0.03', got {raw!r}")
        for tok in raw.replace(";", ",").split(","):
            tok = tok.strip()
            if not tok:
                continue
            key, sep, val = tok.partition("=")
            key = key.strip()
            if sep and not val.strip():
                raise DataError(f"effect '{tok}': missing value after '='")
            name, dot, param = key.partition(".")
            out.append((name.strip(), param.strip() if dot else None, val.strip() if sep else None))
    return out


def parse_effects(spec: Any = None) -> EffectSet:
    """Build an :class:`EffectSet` from a dict, a list of CLI strings, a string, or ``None``.

    Parameters
    ----------
    spec
        - ``None`` or empty: no effect (the nominal model);
        - an :class:`EffectSet`: returned unchanged;
        - a dict ``{effect: value}`` (sets the primary parameter), ``{effect: {param: value}}``,
          ``{effect: None}`` / ``{effect: True}`` (on, default parameters) or
          ``{effect: False}`` (off);
        - a list of strings (or one string, items separated by commas) in the CLI form
          ``"grade=0.03"`` (primary parameter), ``"drivetrain_friction.tau_v=2"`` (a named
          parameter) or ``"hump_shear"`` (on, default parameters).

        Parameters not given take their default (the off value, except ``k_ratio`` = 5 and
        ``n_w`` = the vehicle's road wheels per side, else 5). An effect switched on with all
        parameters at their off values gives the nominal numbers.

    Raises
    ------
    DataError
        Unknown effect or parameter (the message lists the valid ones), a value that is not a
        finite number, out of its admissible range, a parameter given twice, or a pressure
        distribution whose pressure would become negative (``|e| + |alpha| > 1``).
    """
    if spec is None:
        return EffectSet()
    if isinstance(spec, EffectSet):
        return spec
    given: dict[str, dict[str, Any]] = {}

    def put(name: str, param: str | None, value: Any) -> None:
        es = _spec(name)
        d = given.setdefault(name, {})
        if param is None and value is None:
            return
        pname = es.primary if param is None else param
        es.param(pname)
        if pname in d:
            raise DataError(f"{name}.{pname} given twice")
        d[pname] = value

    if isinstance(spec, str):
        spec = [spec]
    if isinstance(spec, Mapping):
        for name, val in spec.items():
            if not isinstance(name, str):
                raise DataError(f"effect names must be strings, got {name!r}; valid effects: {_valid_names()}")
            if isinstance(val, Mapping):
                _spec(name)
                given.setdefault(name, {})
                for k, v in val.items():
                    if v is None:  # "default" (e.g. n_w from the vehicle, as to_dict writes it)
                        es_ = _spec(name)
                        es_.param(str(k))
                        continue
                    put(name, str(k), v)
            elif val is False:  # explicitly off
                _spec(name)
            elif val is None or val is True:
                put(name, None, None)
            else:
                put(name, None, val)
    elif isinstance(spec, (list, tuple)):
        for name, param, val in _split_cli(spec):
            put(name, param, val)
    else:
        raise DataError(f"cannot read effects from {type(spec).__name__}: give a dict, a list of "
                        f"'name=value' strings or None; valid effects: {_valid_names()}")
    entries = []
    for name in _ORDER:
        if name not in given:
            continue
        es = EFFECTS[name]
        vals = []
        for p in es.params:
            if p.name in given[name]:
                v: float | None = _check_value(es, p, given[name][p.name])
            else:
                v = p.off_value if p.default is None and not p.integer else p.default
            vals.append((p.name, v))
        if name == "pressure_distribution":
            d = dict(vals)
            if abs(d["e"]) + abs(d["alpha"]) > 1.0:
                raise DataError(f"pressure_distribution: |e| + |alpha| = {abs(d['e']) + abs(d['alpha']):g} > 1 "
                                "makes the normal pressure negative somewhere on the track")
        entries.append((name, tuple(vals)))
    return EffectSet(tuple(entries))


def parameter_bounds(name: str, param: str, vehicle: Vehicle) -> tuple[float, float]:
    """Finite physical range of an effect parameter for identification, SI.

    The registry's range where it is finite. The drivetrain torques, unbounded in the registry,
    are scaled by the vehicle: ``|tau_c| <= 0.5 W r`` (half the sprocket torque that would
    give a thrust equal to the weight) and ``|tau_v| <= 0.5 W r / w_ref`` with
    ``w_ref = (10 m/s) / r`` (the same loss at a track speed of 10 m/s).
    """
    spec = _spec(name)
    p = spec.param(param)
    lo, hi = p.lower, p.upper
    if name == "drivetrain_friction":
        t = 0.5 * vehicle.weight * vehicle.sprocket_radius
        if param == "tau_v":
            t = t * vehicle.sprocket_radius / 10.0
        lo, hi = max(lo, -t), min(hi, t)
    return float(lo), float(hi)


def parameter_scale(name: str, param: str, vehicle: Vehicle) -> float:
    """Typical magnitude of an effect parameter (variable scaling for the solvers), SI."""
    if name == "drivetrain_friction":
        return 0.01 * vehicle.weight * vehicle.sprocket_radius * (vehicle.sprocket_radius / 10.0 if param == "tau_v"
                                                                  else 1.0)
    if name == "hump_shear" and param == "k_ratio":
        return 5.0
    return 1.0


def effect_structure(effects: Any, vehicle: Vehicle | None = None) -> "EffectSet":
    """The same effects with every identifiable parameter at its default (integers resolved).

    What a cached builder keys on: which effects are on and their fixed integer parameters.
    """
    es = parse_effects(effects)
    out = {}
    for name in es.names:
        out[name] = {p.name: es.value(name, p.name, vehicle) for p in EFFECTS[name].params if p.integer}
    return parse_effects(out)


# --- resolution of numeric or symbolic parameter values -------------------------------------------

class _Values:
    """Resolved parameter values (floats or CasADi expressions) of the effects that are on."""

    def __init__(self, effects: Any, vehicle: Vehicle | None):
        self.vals: dict[str, dict[str, Any]] = {}
        if effects is None:
            return
        if isinstance(effects, EffectSet):
            for name in effects.names:
                self.vals[name] = {p.name: effects.value(name, p.name, vehicle) for p in EFFECTS[name].params}
            return
        if not isinstance(effects, Mapping):
            effects = parse_effects(effects)
            for name in effects.names:
                self.vals[name] = {p.name: effects.value(name, p.name, vehicle) for p in EFFECTS[name].params}
            return
        for name, ps in effects.items():
            es = _spec(name)
            if ps is None or ps is True:
                ps = {}
            elif not isinstance(ps, Mapping):
                ps = {es.primary: ps}
            out = {}
            for p in es.params:
                if p.name in ps:
                    v = ps[p.name]
                    out[p.name] = v if isinstance(v, (ca.SX, ca.MX, ca.DM)) else _check_value(es, p, v)
                elif p.integer:
                    out[p.name] = (float(vehicle.road_wheels) if vehicle is not None and vehicle.road_wheels
                                   else 5.0) if p.default is None else p.default
                else:
                    out[p.name] = p.off_value if p.default is None else p.default
            for k in ps:
                es.param(k)
            if es.name == "pressure_distribution" and isinstance(out["n_w"], (ca.SX, ca.MX)):
                raise DataError("pressure_distribution.n_w must be a fixed integer, not a symbol")
            self.vals[name] = out

    def on(self, name: str) -> bool:
        return name in self.vals

    def __getitem__(self, key: tuple[str, str]) -> Any:
        return self.vals[key[0]][key[1]]


def effect_symbols(effects: Any, sym: type = ca.SX, vehicle: Vehicle | None = None
                   ) -> tuple[dict[str, dict[str, Any]], Any, list[str]]:
    """Symbols for the (non-integer) parameters of the effects that are on, for identification.

    Parameters
    ----------
    effects
        Anything :func:`parse_effects` accepts; only which effects are on (and ``n_w``) matters.
    sym
        ``casadi.SX`` or ``casadi.MX``.
    vehicle
        Resolves ``n_w`` when it was not given.

    Returns
    -------
    mapping, vector, labels
        ``{effect: {param: symbol-or-fixed-integer}}`` (pass it as ``effects`` to the builders),
        the column vector of the symbols, and their labels ``"effect.param"`` in vector order.
    """
    es = parse_effects(effects)
    mapping: dict[str, dict[str, Any]] = {}
    syms, labels = [], []
    for name in es.names:
        mapping[name] = {}
        for p in EFFECTS[name].params:
            if p.integer:
                mapping[name][p.name] = es.value(name, p.name, vehicle)
                continue
            s = sym.sym(f"{name}.{p.name}")
            mapping[name][p.name] = s
            syms.append(s)
            labels.append(f"{name}.{p.name}")
    vec = ca.vertcat(*syms) if syms else sym(0, 1)
    return mapping, vec, labels


# --- building blocks ----------------------------------------------------------------------------------

def smooth_sign(x, width: float | None):
    """``sgn(x)`` for ``|x| >= width``, a C1 cubic ramp through 0 inside (``width`` None or 0: +1).

    With ``width`` ``None`` the term is the textbook constant (forward motion assumed).
    """
    if not width:
        return 1.0
    s = x / width
    ramp = s * (1.5 - 0.5 * s * s)
    return ca.if_else(x >= width, 1.0, ca.if_else(x <= -width, -1.0, ramp))


def effective_mass(vehicle: Vehicle, effects: Any = None):
    """Actual mass ``m (1 + delta)`` (``m`` when ``mass_error`` is off), kg."""
    ev = effects if isinstance(effects, _Values) else _Values(effects, vehicle)
    m = vehicle.mass
    return m * (1 + ev["mass_error", "delta"]) if ev.on("mass_error") else m


def effective_weight(W, vehicle: Vehicle, effects: Any = None):
    """Actual weight ``W (1 + delta)`` from the nominal ``W`` (``mass_error``), N."""
    ev = effects if isinstance(effects, _Values) else _Values(effects, vehicle)
    return W * (1 + ev["mass_error", "delta"]) if ev.on("mass_error") else W


def effective_normal_load(W, vehicle: Vehicle, effects: Any = None):
    """Actual normal load ``W (1 + delta) cos(theta)`` from the nominal ``W`` (``mass_error``, ``grade``)."""
    ev = effects if isinstance(effects, _Values) else _Values(effects, vehicle)
    N = effective_weight(W, vehicle, ev)
    return N * ca.cos(ev["grade", "theta_rad"]) if ev.on("grade") else N


def effective_radius(vehicle: Vehicle, effects: Any = None):
    """Effective track radius ``r (1 + eps)`` (``r`` when ``radius_error`` is off), m."""
    ev = effects if isinstance(effects, _Values) else _Values(effects, vehicle)
    r = vehicle.sprocket_radius
    return r * (1 + ev["radius_error", "eps"]) if ev.on("radius_error") else r


def motion_resistance(v, slip, vehicle: Vehicle, effects: Any = None, W=None,
                      standstill_speed: float | None = DEFAULT_STANDSTILL_SPEED):
    """Longitudinal motion resistance, N: nominal ``W mu_r`` plus the resistance effects.

    ``R = N (mu_r + mu_s |i|) sgn(v) + N mu_v v + W_a sin(theta)`` with ``N`` the actual normal
    load (:func:`effective_normal_load`) and ``W_a`` the actual weight. ``sgn(v)`` is
    :func:`smooth_sign` with width ``standstill_speed`` (exactly 1 for ``v >= standstill_speed``;
    ``None``: the constant textbook term, forward motion assumed).

    Parameters
    ----------
    v, slip
        Vehicle speed (m/s) and track slip (-), floats or CasADi expressions.
    W
        Nominal weight, N (default the vehicle's).
    """
    ev = effects if isinstance(effects, _Values) else _Values(effects, vehicle)
    W = vehicle.weight if W is None else W
    N = effective_normal_load(W, vehicle, ev)
    coef = vehicle.rolling_resistance
    if ev.on("slip_sinkage"):
        coef = coef + ev["slip_sinkage", "mu_s"] * ca.fabs(slip)
    R = N * coef
    if standstill_speed:
        R = R * smooth_sign(v, standstill_speed)
    if ev.on("speed_resistance"):
        R = R + N * ev["speed_resistance", "mu_v"] * v
    if ev.on("grade"):
        R = R + effective_weight(W, vehicle, ev) * ca.sin(ev["grade", "theta_rad"])
    return R


def torque_loss(w, vehicle: Vehicle, effects: Any = None,
                standstill_speed: float | None = DEFAULT_STANDSTILL_SPEED):
    """Drivetrain torque loss ``tau_c sgn(w) + tau_v w`` (0 when ``drivetrain_friction`` is off), N m.

    ``sgn(w)`` is :func:`smooth_sign` with width ``standstill_speed / r``.
    """
    ev = effects if isinstance(effects, _Values) else _Values(effects, vehicle)
    if not ev.on("drivetrain_friction"):
        return 0.0
    tc, tv = ev["drivetrain_friction", "tau_c"], ev["drivetrain_friction", "tau_v"]
    sgn = smooth_sign(w, standstill_speed / vehicle.sprocket_radius) if standstill_speed else 1.0
    return tc * sgn + tv * w


def _horner(coefs, x):
    out = 0.0
    for c in reversed(coefs):
        out = c + x * out
    return out


#: Taylor coefficients of m1(X) = sum_k -(-1)^k k / ((k+1)(k+2) k!) X^k, k = 0..20.
_M1_COEFS = [-((-1) ** k) * k / ((k + 1) * (k + 2) * math.factorial(k)) for k in range(21)]
_M1_SWITCH = 1.0


def _m1(X):
    """Mean over the track of (2x/l - 1)(1 - exp(-X x/l)), extended as an odd function of X.

    Series below |X| = 1 (no cancellation), written with X and |X| so that automatic
    differentiation gives the true slope 1/6 at X = 0.
    """
    a = ca.fabs(X)
    series = 0.0
    for k in range(len(_M1_COEFS) - 1, 0, -1):  # sum_k c_k sign(X) |X|^k, Horner in |X|
        series = _M1_COEFS[k] + a * series
    series = X * series
    safe = ca.if_else(a < _M1_SWITCH, 1.0, a)
    one_minus = -ca.expm1(-safe)
    exact = ca.sign(X) * (one_minus / safe - 2 * (one_minus - safe * ca.exp(-safe)) / (safe * safe))
    return ca.if_else(a < _M1_SWITCH, series, exact)


def _mc(X, n_w):
    """Mean over the track of cos(2 pi n_w x/l)(1 - exp(-X x/l)), odd in X, integer n_w (exact, finite at 0)."""
    w = 2 * math.pi * n_w
    return -(-ca.expm1(-ca.fabs(X))) * X / (X * X + w * w)


def thrust_with_effects(slip, c, phi, K, W, vehicle: Vehicle, effects: Any = None, model: str = "full"):
    """Tractive force of both tracks with the effects that change it (symbolic), N.

    ``F = 2 b * integral over the track of (c + p(x) tan(phi)) s(i x) dx`` in closed form, with
    ``s`` the shear law (Janosi-Hanamoto, or :func:`softening_shear` for ``hump_shear``) and
    ``p`` the pressure (uniform, or :func:`pressure_profile` for ``pressure_distribution``).
    The normal load is the actual one, ``W (1 + delta) cos(theta)`` (``mass_error``,
    ``grade``). Skid: ``F(i) = -F(|i|)`` (every term is an odd function of the slip).
    ``F(0) = 0`` with exact derivatives (series near 0). With no shear-changing effect on this
    is :func:`~.traction.thrust_expr` itself.

    Parameters
    ----------
    slip, c, phi, K
        Track slip (-), cohesion (Pa), friction angle (rad), shear modulus (m): floats or CasADi.
    W
        NOMINAL normal load, N (e.g. ``vehicle.weight``, or a rig's set load).
    vehicle
        Gives l, b (and r, road wheels).
    effects
        An :class:`EffectSet`, anything :func:`parse_effects` accepts, or a mapping
        ``{effect: {param: value-or-symbol}}`` (see :func:`effect_symbols`).
    model
        ``"full"`` or ``"cohesion-free"`` (drops ``A c``).
    """
    check_model(model)
    ev = effects if isinstance(effects, _Values) else _Values(effects, vehicle)
    N = effective_normal_load(W, vehicle, ev)
    l, b = vehicle.track_length, vehicle.track_width
    if not (ev.on("hump_shear") or ev.on("pressure_distribution")):
        return thrust_expr(slip, c, phi, K, N, l, b, model)
    f_max = max_thrust_expr(c, phi, N, 2 * b * l, model)
    fric = N * ca.tan(phi)

    def mean(K_):
        """Force of the shear law 1 - exp(-|i| x / K_) under the (possibly non-uniform) pressure."""
        out = f_max * slip_factor(slip, l, K_)
        if ev.on("pressure_distribution"):
            X = slip * l / K_
            out = out + fric * (ev["pressure_distribution", "e"] * _m1(X)
                                + ev["pressure_distribution", "alpha"] * _mc(X, ev["pressure_distribution", "n_w"]))
        return out

    total = mean(K)
    if ev.on("hump_shear"):
        drop, kr = ev["hump_shear", "drop"], ev["hump_shear", "k_ratio"]
        # s = (1 - u)(1 - drop (1 - u_s)) = (1 - u) - drop [(1 - u) + (1 - u_s) - (1 - u u_s)]
        total = total - drop * (total + mean(K * kr) - mean(K * kr / (1 + kr)))
    return total


@lru_cache(maxsize=256)
def _thrust_fn(vehicle: Vehicle, effects: EffectSet, model: str) -> ca.Function:
    s = [ca.SX.sym(n) for n in ("slip", "c", "phi", "K", "W")]
    F = thrust_with_effects(*s, vehicle, effects, model)
    return ca.Function("thrust_effects", s, [F], ["slip", "c", "phi", "K", "W"], ["F"])


def thrust_with_effects_function(vehicle: Vehicle, effects: Any = None, model: str = "full") -> ca.Function:
    """Cached CasADi Function ``F(slip, c, phi, K, W)`` (W nominal) with numeric effects."""
    check_model(model)
    return _thrust_fn(vehicle, parse_effects(effects), model)


def tractive_force_with_effects(slip, soil: Soil, vehicle: Vehicle, effects: Any = None, model: str = "full",
                                normal_load=None) -> np.ndarray:
    """Numpy tractive force (N) with effects, shaped like the broadcast of ``slip`` and ``normal_load``.

    ``normal_load`` is the nominal load (default the vehicle's weight).
    """
    W = vehicle.weight if normal_load is None else normal_load
    s, Wb = np.broadcast_arrays(np.asarray(slip, dtype=float), np.asarray(W, dtype=float))
    if s.size == 0:
        return np.zeros(s.shape)
    f = thrust_with_effects_function(vehicle, effects, model)
    out = f(s.reshape(1, -1), soil.cohesion, soil.friction_angle, soil.shear_modulus, Wb.reshape(1, -1))
    return np.asarray(out, dtype=float).reshape(s.shape)


def softening_shear(j, K: float, drop: float = 0.0, k_ratio: float = 5.0) -> np.ndarray:
    """Normalised shear stress of the ``hump_shear`` law, ``tau / (c + p tan(phi))`` (numpy).

    ``s(j) = (1 - exp(-j/K)) [1 - drop (1 - exp(-j/(k_ratio K)))]``; ``drop = 0`` is
    Janosi-Hanamoto. Residual value ``1 - drop``.
    """
    j = np.asarray(j, dtype=float)
    return -np.expm1(-j / K) * (1 - drop * -np.expm1(-j / (k_ratio * K)))


def wong_type_b_shear(j, K_r: float, K_w: float) -> np.ndarray:
    """Wong's type B shear law ``tau / tau_max`` as written in DESIGN.md section 6 (numpy), for comparison.

    ``K_r {1 + [1/(K_r (1 - 1/e)) - 1] exp(1 - j/K_w)} (1 - exp(-j/K_w))``: equal to 1 at
    ``j = K_w`` (its normalisation; the exact maximum lies slightly before K_w and a few percent
    above 1 for K_r < 1), tending to the residual ``K_r``.
    """
    j = np.asarray(j, dtype=float)
    amp = 1.0 / (K_r * (1.0 - math.exp(-1.0))) - 1.0
    return K_r * (1.0 + amp * np.exp(1.0 - j / K_w)) * -np.expm1(-j / K_w)


def pressure_profile(x, vehicle: Vehicle, effects: Any = None, W=None) -> np.ndarray:
    """Normal pressure p(x) under one track, Pa, x from the front (numpy; uniform when off).

    ``p_mean = N / A`` with the actual normal load N.
    """
    ev = _Values(effects, vehicle)
    W = vehicle.weight if W is None else W
    p_mean = float(effective_normal_load(W, vehicle, ev)) / vehicle.contact_area
    x = np.asarray(x, dtype=float)
    l = vehicle.track_length
    shape = np.ones_like(x)
    if ev.on("pressure_distribution"):
        e, a, n = (float(ev["pressure_distribution", k]) for k in ("e", "alpha", "n_w"))
        shape = shape + e * (2 * x / l - 1) + a * np.cos(2 * math.pi * n * x / l)
    return p_mean * shape


#: Track speed ``r w`` of a drawbar-pull rig when none is given, m/s (sets the vehicle speed).
DEFAULT_RIG_SPEED = 0.5
#: What a slip sweep may have measured (the CSV column is the name with ``_N``).
SWEEP_MEASURES = ("tractive_force", "drawbar_pull")


def rig_true_slip(i_app, vehicle: Vehicle, effects: Any = None):
    """True slip from the slip a rig computes with the nominal radius (``radius_error``).

    ``1 - v / (r_eff w) = (i + eps) / (1 + eps)``: ``eps = 0`` gives ``i`` exactly.
    """
    ev = effects if isinstance(effects, _Values) else _Values(effects, vehicle)
    if not ev.on("radius_error"):
        return i_app
    eps = ev["radius_error", "eps"]
    return (i_app + eps) / (1 + eps)


def sweep_measurement(i_app, W, c, phi, K, vehicle: Vehicle, effects: Any = None, model: str = "full",
                      measured: str = "tractive_force", rig_speed: float = DEFAULT_RIG_SPEED):
    """What a drawbar-pull rig reports at apparent slip ``i_app`` and nominal load ``W`` (symbolic).

    The rig runs the track at speed ``r w = rig_speed`` (so ``v = rig_speed (1 - i_app)``)
    and measures the drawbar pull ``DP = F(i) - R`` with ``F`` the thrust with effects
    (:func:`thrust_with_effects`, at the true slip :func:`rig_true_slip`) and ``R`` the actual
    motion resistance (:func:`motion_resistance`). A rig reporting "tractive force" adds the
    NOMINAL resistance back (the usual conversion): ``F_rep = DP + W mu_r``, so resistance
    effects show there as lost force. With no effect on, ``F_rep = F(i)`` exactly.

    Returns
    -------
    i_true, thrust, reported
        True slip, thrust (N) and the reported quantity (N).
    """
    if measured not in SWEEP_MEASURES:
        raise DataError(f"unknown measured quantity {measured!r}; expected one of {SWEEP_MEASURES}")
    ev = effects if isinstance(effects, _Values) else _Values(effects, vehicle)
    v = rig_speed * (1 - i_app)
    i_true = rig_true_slip(i_app, vehicle, ev)
    F = thrust_with_effects(i_true, c, phi, K, W, vehicle, ev, model)
    dp = F - motion_resistance(v, i_true, vehicle, ev, W=W)
    if measured == "drawbar_pull":
        return i_true, F, dp
    return i_true, F, dp + motion_resistance(v, i_true, vehicle, None, W=W)


@lru_cache(maxsize=64)
def _normal_load_fn(vehicle: Vehicle, structure: EffectSet) -> ca.Function:
    mapping, vec, _ = effect_symbols(structure, ca.SX, vehicle)
    W = ca.SX.sym("W")
    N = effective_normal_load(W, vehicle, mapping)
    N = N if isinstance(N, ca.SX) else ca.SX(N)
    return ca.Function("normal_load", [W, vec], [N, ca.jacobian(N, vec)], ["W", "e"], ["N", "dN_de"])


def normal_load_function(vehicle: Vehicle, effects: Any = None) -> ca.Function:
    """Cached Function ``(W, e) -> (N, dN/de)``: actual normal load from the nominal ``W`` and the
    vector ``e`` of the identifiable effect parameters (order of :func:`effect_symbols`)."""
    return _normal_load_fn(vehicle, effect_structure(effects, vehicle))
