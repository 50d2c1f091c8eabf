"""Bevameter soil tests: shear tests (c, phi, K) and plate sinkage tests (k_c, k_phi, n).

Public names
------------
:func:`fit_soil_test`
    A :class:`~soiltrack.soilmodel.ShearTest` or :class:`~soiltrack.soilmodel.PlateTest` ->
    :class:`~soiltrack.identify.estimates.estimate.Estimate`, the library's one record (``SoilTestFit`` is
    its earlier name): bounded IPOPT, 95 % intervals, what is not identifiable.
:func:`fit_shear_test`, :func:`fit_plate_test`, :class:`PlateBounds`
    The two fits.
:func:`predict_drawbar_pull`, :class:`DrawbarPrediction`
    A track's drawbar pull from a shear and a plate fit, with its interval.
"""

from .plate import PLATE_BOUNDS, PlateBounds, fit_plate_test
from .prediction import DrawbarPrediction, predict_drawbar_pull
from .result import SOIL_TEST_KINDS, SoilTestFit
from .shear import fit_shear_test
from .dispatch import fit_soil_test

__all__ = [
    "fit_soil_test",
    "fit_shear_test",
    "fit_plate_test",
    "PlateBounds",
    "PLATE_BOUNDS",
    "SoilTestFit",
    "SOIL_TEST_KINDS",
    "predict_drawbar_pull",
    "DrawbarPrediction",
]
