"""What :func:`soiltrack.identify.fit` checks before it fits, and the kinds it hands on.

``fit(data, running_gear=None, *, ...)`` takes every kind of data: a sweep or drive log with a
tracked :class:`~soiltrack.soilmodel.Vehicle`, a wheel sweep with a
:class:`~soiltrack.soilmodel.rigid_wheel.RigidWheel`, a bevameter test with no running gear. Every
option is keyword-only and checked here, before any solve (scipy's style): an option that does not
apply to the data kind, or a running gear of the wrong kind, raises
:class:`~soiltrack.soilmodel.DataError` naming it.
"""

from __future__ import annotations

from typing import Any

from ..soilmodel.data import DriveLog, PlateTest, ShearTest, SlipData
from ..soilmodel.errors import DataError
from ..soilmodel.rigid_wheel import RigidWheel
from ..soilmodel.soil import SoilBounds
from ..soilmodel.vehicle import Vehicle
from ..soilmodel.wheel_sweep import WheelSweep
from .settings import SETTING_NAMES

__all__ = ["check_fit_options", "fit_other_kind", "SWEEP_OPTIONS", "MODELS"]

#: The soil models of a track's and a wheel's fit.
MODELS = ("full", "cohesion-free")
#: The ``**options`` a slip sweep takes (beside :data:`~soiltrack.identify.settings.SETTING_NAMES`).
SWEEP_OPTIONS = ("rig_speed", "sigma", "sigma_known", "slip_noise", "intervals", "resistance")
#: What the track's fit takes as keywords; a wheel takes only the ones it names.
_WHEEL_KEYWORDS = ("model", "bounds", "effects", "fixed", "strict")


def check_fit_options(
    data,
    running_gear,
    *,
    model: str,
    method: str,
    bounds,
    x0,
    engine,
    effects,
    fixed,
    settings,
    options: dict[str, Any],
) -> str | None:
    """Check the running gear and every option against the data kind; return ``"wheel"`` or
    ``"bevameter"`` for the kinds :func:`fit_other_kind` fits, None for a track's sweep or log."""
    if isinstance(data, (ShearTest, PlateTest)):
        if running_gear is not None:
            raise DataError(
                f"a bevameter test is fitted without a running gear (the soil itself was measured); "
                f"got running_gear={type(running_gear).__name__}",
                file=data.source,
            )
        given = _given(
            model=model,
            method=method,
            bounds=bounds,
            x0=x0,
            engine=engine,
            effects=effects,
            fixed=fixed,
            settings=settings,
        )
        _refuse(given + sorted(options), "a bevameter test")
        return "bevameter"
    if running_gear is None:
        raise DataError(
            f"fit needs a running gear for {type(data).__name__}: a Vehicle for sweeps and drive logs, a "
            "RigidWheel for wheel sweeps (only a bevameter test is fitted without one)"
        )
    if model not in MODELS:
        raise DataError(f"model must be one of {MODELS}, got {model!r}")
    if isinstance(running_gear, RigidWheel):
        if not isinstance(data, (WheelSweep, SlipData)):
            raise DataError(f"a rigid wheel fits a wheel sweep (WheelSweep or SlipData), got {type(data).__name__}")
        given = _given(method=method, x0=x0, engine=engine, settings=settings)
        _refuse(given + sorted(options), f"a rigid wheel (it takes {', '.join(_WHEEL_KEYWORDS)})")
        if bounds is not None and isinstance(bounds, SoilBounds):
            raise DataError("bounds for a rigid wheel are a WheelBounds (seven parameters), got a SoilBounds")
        return "wheel"
    if not isinstance(running_gear, Vehicle):
        raise DataError(f"running_gear must be a Vehicle, a RigidWheel or None, got {type(running_gear).__name__}")
    if not isinstance(data, (SlipData, DriveLog)):
        raise DataError(f"a tracked vehicle fits SlipData or a DriveLog, got {type(data).__name__}")
    if bounds is not None and not isinstance(bounds, SoilBounds):
        raise DataError(f"bounds must be a SoilBounds, got {type(bounds).__name__}")
    if isinstance(data, DriveLog):  # the drive-log fit checks its own options before it solves
        from .drivelog.budget import check_fit_budget

        # never killed: the estimate against max_memory (bytes; default half the available memory), up front
        check_fit_budget(
            data.n_samples,
            source=data.source,
            max_memory=options.pop("max_memory", None),
            effects=bool(effects),
            latent_slips=str(options.get("latent_slips", "auto")),
        )
        return None
    allowed = set(SWEEP_OPTIONS) | set(SETTING_NAMES)
    unknown = sorted(set(options) - allowed)
    kind = "a slip sweep"
    if unknown:
        raise DataError(
            f"fit: unknown option(s) {', '.join(repr(u) for u in unknown)} for {kind}; it takes "
            f"{', '.join(sorted(allowed))}"
        )
    return None


def _given(**kw: Any) -> list[str]:
    """Names of the keywords given a value other than their default."""
    defaults = {"model": "full", "method": "ipopt"}
    return [k for k, v in kw.items() if v is not None and v != defaults.get(k, None)]


def _refuse(names: list[str], what: str) -> None:
    if names:
        raise DataError(f"fit: option(s) {', '.join(repr(n) for n in names)} do not apply to {what}")


def fit_other_kind(data, running_gear, *, model: str, bounds, effects, fixed, strict: bool):
    """Fit a wheel sweep with its rigid wheel or a bevameter test (checked by :func:`check_fit_options`)."""
    res: Any
    if running_gear is None:
        from .soiltests import fit_soil_test

        res = fit_soil_test(data)
    else:
        from .wheel import WheelFitOptions, fit_wheel

        held = dict(fixed or {})
        if model == "cohesion-free":
            held.setdefault("cohesion", 0.0)
        kw: dict[str, Any] = {"fixed": held, "effects": tuple(effects or ())}
        if bounds is not None:
            kw["bounds"] = bounds
        res = fit_wheel(_wheel_sweep(data), running_gear, WheelFitOptions(**kw))
    if strict and not res.success:
        raise RuntimeError(f"soil identification failed: {res.fit_outcome.reason}")
    return res


def _wheel_sweep(data) -> WheelSweep:
    """A wheel sweep from a drawbar-pull :class:`SlipData` with the load per row (or as it is)."""
    if isinstance(data, WheelSweep):
        return data
    if data.measured != "drawbar_pull" or data.normal_load is None:
        raise DataError(
            "a rigid wheel's sweep needs the drawbar pull and the normal load per row "
            "(slip,drawbar_pull_N,normal_load_N[,sinkage_m])",
            file=data.source,
        )
    return WheelSweep(
        slip=data.slip, drawbar_pull=data.drawbar_pull, normal_load=data.normal_load, sinkage=data.sinkage
    )


#: Public name of the wheel sweep of SlipData (the joint fit of several data sets uses it).
wheel_sweep_of = _wheel_sweep
