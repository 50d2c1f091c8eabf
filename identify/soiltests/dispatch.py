"""One entry for any bevameter test: the fit chosen by the kind of test."""

from __future__ import annotations

from ...soilmodel import DataError, PlateTest, ShearTest
from ...soilmodel.bevameter_records import AnnulusTest
from .plate import PlateBounds, fit_plate_test
from ..estimates.estimate import Estimate
from .shear import fit_shear_test

__all__ = ["fit_soil_test", "is_soil_test"]


def is_soil_test(data) -> bool:
    """Whether ``data`` is a bevameter test (shear or plate)."""
    return isinstance(data, (ShearTest, PlateTest, AnnulusTest))


def fit_soil_test(test: ShearTest | PlateTest | AnnulusTest, *, negative_kc: bool = False) -> Estimate:
    """Fit a bevameter test with its default bounds (:func:`fit_shear_test` or :func:`fit_plate_test`).

    ``negative_kc``: a plate test's k_c fitted freely (flagged when negative) instead of held at >= 0.
    """
    if isinstance(test, (ShearTest, AnnulusTest)):
        if negative_kc:
            raise DataError("--negative-kc applies to plate tests only", file=test.source)
        return fit_shear_test(test)
    if isinstance(test, PlateTest):
        return fit_plate_test(test, PlateBounds(negative_kc=negative_kc))
    raise DataError(f"not a bevameter test: {type(test).__name__} (expected ShearTest or PlateTest)")
