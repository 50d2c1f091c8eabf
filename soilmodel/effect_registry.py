"""Unmodelled physical effects (docs/physics.md) as switchable augmentations of the model.

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
    Strain-softening soil whose shear stress peaks, then falls. See :func:`~.thrust_effects.softening_shear`.
``pressure_distribution`` (``e``, -, primary; ``alpha``, -; ``n_w``, -)
    Non-uniform normal pressure ``p(x) = p_mean [1 + e (2x/l - 1) + alpha cos(2 pi n_w x / l)]``
    with x from the front of the contact (``e > 0``: load shifted to the rear).
``mass_error`` (``delta``, -)
    Actual mass ``m (1 + delta)``, and the weight with it.

The physics of each effect lives in :mod:`.effect_terms` (resistance, torque, radius, mass)
and :mod:`.thrust_effects` (thrust with effects); :mod:`.rig` is what a drawbar-pull rig reports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

import casadi as ca

from .errors import DataError
from .vehicle import Vehicle

__all__ = [
    "ParamSpec",
    "EffectSpec",
    "EFFECTS",
    "EffectSet",
    "parse_effects",
    "effect_symbols",
    "parameter_bounds",
    "parameter_scale",
    "effect_structure",
]

_INF = math.inf


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
    physical_sign
        +1 when the effect as named has this parameter >= 0 (a resistance that GROWS with speed or
        slip); the range stays signed, so that a fit can say the data want the opposite, which is
        then another effect imitating this one. 0: either sign is physical.
    """

    name: str
    unit: str
    description: str
    off_value: float
    default: float | None = None
    lower: float = -_INF
    upper: float = _INF
    integer: bool = False
    physical_sign: int = 0


@dataclass(frozen=True)
class EffectSpec:
    """One unmodelled effect: its name, physics, parameters and CLI primary parameter.

    Attributes
    ----------
    name, description
        Contract name (docs/physics.md) and physics in words.
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
        raise DataError(f"effect '{self.name}' has no parameter '{name}'; valid: {[p.name for p in self.params]}")

    @property
    def param_names(self) -> tuple[str, ...]:
        """Names of the parameters, in order."""
        return tuple(p.name for p in self.params)


#: Registry of the unmodelled effects of docs/physics.md (names are a public contract).
EFFECTS: dict[str, EffectSpec] = {
    "grade": EffectSpec(
        "grade",
        "unknown constant slope (or any constant extra motion resistance, e.g. Bekker compaction): "
        "normal load W cos(theta), extra resistance W sin(theta)",
        (ParamSpec("theta_rad", "rad", "slope angle, positive uphill", 0.0, lower=-1.2, upper=1.2),),
        "theta_rad",
    ),
    "speed_resistance": EffectSpec(
        "speed_resistance",
        "motion resistance growing with speed: N (mu_r + mu_v v)",
        (
            ParamSpec(
                "mu_v", "s/m", "speed coefficient of motion resistance", 0.0, lower=-1.0, upper=1.0, physical_sign=1
            ),
        ),
        "mu_v",
        ("drive", "sweep"),
    ),
    "slip_sinkage": EffectSpec(
        "slip_sinkage",
        "slip-induced sinkage: resistance N (mu_r + mu_s |i|)",
        (ParamSpec("mu_s", "-", "slip coefficient of motion resistance", 0.0, lower=-1.0, upper=2.0, physical_sign=1),),
        "mu_s",
    ),
    "drivetrain_friction": EffectSpec(
        "drivetrain_friction",
        "torque lost between the torque sensor and the track: tau_c sgn(w) + tau_v w",
        (
            ParamSpec(
                "tau_c", "N m", "Coulomb torque loss (both tracks)", 0.0, lower=-_INF, upper=_INF, physical_sign=1
            ),
            ParamSpec(
                "tau_v",
                "N m s/rad",
                "viscous torque loss coefficient (both tracks)",
                0.0,
                lower=-_INF,
                upper=_INF,
                physical_sign=1,
            ),
        ),
        "tau_c",
        ("drive",),
    ),
    "radius_error": EffectSpec(
        "radius_error",
        "effective track radius r (1 + eps) in the slip and in the torque arm",
        (ParamSpec("eps", "-", "relative error of the effective radius", 0.0, lower=-0.5, upper=0.5),),
        "eps",
    ),
    "hump_shear": EffectSpec(
        "hump_shear",
        "strain-softening soil: s(j) = (1 - exp(-j/K)) [1 - drop (1 - exp(-j/(k_ratio K)))]; "
        "shear stress peaks, then falls to the residual fraction 1 - drop",
        (
            ParamSpec(
                "drop",
                "-",
                "fraction of the Mohr-Coulomb strength lost at large shear displacement "
                "(residual = 1 - drop); 0 = Janosi-Hanamoto",
                0.0,
                lower=0.0,
                upper=0.95,
            ),
            ParamSpec(
                "k_ratio",
                "-",
                "softening displacement modulus over K (K_s = k_ratio K); a hump needs k_ratio > 1",
                5.0,
                default=5.0,
                lower=0.05,
                upper=1000.0,
            ),
        ),
        "drop",
        ("sweep", "drive"),
    ),
    "pressure_distribution": EffectSpec(
        "pressure_distribution",
        "non-uniform normal pressure p(x) = p_mean [1 + e (2x/l - 1) + alpha cos(2 pi n_w x / l)], x from the front",
        (
            ParamSpec("e", "-", "front/rear shift (e > 0: more load on the rear)", 0.0, lower=-1.0, upper=1.0),
            ParamSpec("alpha", "-", "amplitude of the road-wheel pressure peaks", 0.0, lower=-1.0, upper=1.0),
            ParamSpec(
                "n_w",
                "-",
                "number of road-wheel periods along the track (default: the vehicle's road wheels per side, else 5)",
                5.0,
                default=None,
                lower=1.0,
                upper=50.0,
                integer=True,
            ),
        ),
        "e",
        ("sweep", "drive"),
    ),
    "mass_error": EffectSpec(
        "mass_error",
        "actual mass (payload) differs from the nominal: m (1 + delta), and W with it",
        (ParamSpec("delta", "-", "relative mass error", 0.0, lower=-0.9, upper=10.0),),
        "delta",
    ),
}

_ORDER = tuple(EFFECTS)


def _valid_names() -> str:
    return ", ".join(_ORDER)


def effect_spec(name: str) -> EffectSpec:
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
        raise DataError(
            f"{spec.name}.{p.name} = {v:g} is outside its admissible range [{p.lower:g}, {p.upper:g}] {p.unit}"
        )
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
        spec = effect_spec(name)
        for n, ps in self.entries:
            if n == name:
                return dict(ps)
        return {p.name: p.off_value for p in spec.params}

    def value(self, name: str, param: str, vehicle: Vehicle | None = None) -> float:
        """One parameter value; ``n_w = None`` is resolved from ``vehicle`` (road wheels, else 5)."""
        spec = effect_spec(name)
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
            effect_spec(n)
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
        es = effect_spec(name)
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
                effect_spec(name)
                given.setdefault(name, {})
                for k, v in val.items():
                    if v is None:  # "default" (e.g. n_w from the vehicle, as to_dict writes it)
                        es_ = effect_spec(name)
                        es_.param(str(k))
                        continue
                    put(name, str(k), v)
            elif val is False:  # explicitly off
                effect_spec(name)
            elif val is None or val is True:
                put(name, None, None)
            else:
                put(name, None, val)
    elif isinstance(spec, (list, tuple)):
        for name, param, val in _split_cli(spec):
            put(name, param, val)
    else:
        raise DataError(
            f"cannot read effects from {type(spec).__name__}: give a dict, a list of "
            f"'name=value' strings or None; valid effects: {_valid_names()}"
        )
    entries = []
    for name in _ORDER:
        if name not in given:
            continue
        es = EFFECTS[name]
        vals = []
        for p in es.params:
            if p.name in given[name]:
                pval: float | None = _check_value(es, p, given[name][p.name])
            else:
                pval = p.off_value if p.default is None and not p.integer else p.default
            vals.append((p.name, pval))
        if name == "pressure_distribution":
            d = dict(vals)
            e, alpha = d["e"], d["alpha"]
            if e is None or alpha is None:  # impossible: both are real parameters with a float off value
                raise RuntimeError("pressure_distribution: e or alpha has no value")
            if abs(e) + abs(alpha) > 1.0:
                raise DataError(
                    f"pressure_distribution: |e| + |alpha| = {abs(e) + abs(alpha):g} > 1 "
                    "makes the normal pressure negative somewhere on the track"
                )
        entries.append((name, tuple(vals)))
    return EffectSet(tuple(entries))


def parameter_bounds(name: str, param: str, vehicle: Vehicle) -> tuple[float, float]:
    """Finite physical range of an effect parameter for identification, SI.

    The registry's range where it is finite. The drivetrain torques, unbounded in the registry,
    are scaled by the vehicle: ``|tau_c| <= 0.5 W r`` (half the sprocket torque that would
    give a thrust equal to the weight) and ``|tau_v| <= 0.5 W r / w_ref`` with
    ``w_ref = (10 m/s) / r`` (the same loss at a track speed of 10 m/s).
    """
    spec = effect_spec(name)
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
        return (
            0.01
            * vehicle.weight
            * vehicle.sprocket_radius
            * (vehicle.sprocket_radius / 10.0 if param == "tau_v" else 1.0)
        )
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


class EffectValues:
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
            es = effect_spec(name)
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
                    out[p.name] = (
                        (float(vehicle.road_wheels) if vehicle is not None and vehicle.road_wheels else 5.0)
                        if p.default is None
                        else p.default
                    )
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


def effect_symbols(
    effects: Any, sym: type[ca.SX] | type[ca.MX] = ca.SX, vehicle: Vehicle | None = None
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
    syms: list[Any] = []  # SX or MX symbols, as ``sym``
    labels: list[str] = []
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
