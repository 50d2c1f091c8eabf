"""Grousers beyond the shear radius: Bekker's side-shear multipliers of the shear strength.

A running gear with grousers of height h shears the soil on the surface through the grouser
tips (the shear radius ``r_s = r + h`` of :mod:`.wheel`) and, in addition, along the two sides of
the soil block held between neighbouring grousers. Bekker's thrust of a grousered running gear of
width b (Bekker, Theory of Land Locomotion, 1956; quoted in Wong, Theory of Ground Vehicles, ch. 2,
thrust with grousers) is the smooth one with the cohesive and the frictional parts multiplied::

    F = A c (1 + 2 h / b) + W tan(phi) (1 + 0.64 (h / b) arccot(h / b))

the ``2 h / b``: cohesion on the two side faces (each of area h per unit length) beside the base
of width b; the ``0.64 (h / b) arccot(h / b)``: the frictional side thrust from the lateral soil
pressure on those faces. Applied locally to the Janosi-Hanamoto stress of the rim, the shear
strength is ``c f_c + sigma tan(phi) f_phi``. At h = 0 both factors are exactly 1 (the smooth
wheel; the wheel model then does not build them at all). Here ``arccot(x) = pi / 2 - atan(x)``
(smooth at 0).

The grouser spacing does not enter Bekker's formula: it assumes the spacing short enough that the
soil between two grousers moves with the wheel as a block (the shear surface at the tips). The
functions take floats or CasADi expressions (one home: :func:`grouser_factors_expr`).
"""

from __future__ import annotations

import math

import casadi as ca

__all__ = ["GROUSER_MODELS", "grouser_factors_expr", "BEKKER_SIDE_FRICTION"]

#: Grouser models of :class:`~soiltrack.soilmodel.wheel.WheelSettings`: ``bekker`` (the shear radius
#: and Bekker's side-shear multipliers) or ``shear_radius`` (the shear radius only, the library's model
#: before: grousers then only rescale K).
GROUSER_MODELS = ("bekker", "shear_radius")
#: Bekker's coefficient of the frictional side thrust.
BEKKER_SIDE_FRICTION = 0.64


def grouser_factors_expr(h, b):
    """``(f_c, f_phi)``: Bekker's multipliers of the cohesive and the frictional shear strength.

    Parameters
    ----------
    h
        Grouser height, m (>= 0; float or CasADi).
    b
        Width of the running gear, m (> 0).
    """
    x = h / b
    atan = ca.atan if isinstance(x, (ca.SX, ca.MX, ca.DM)) else math.atan
    return 1 + 2 * x, 1 + BEKKER_SIDE_FRICTION * x * (math.pi / 2 - atan(x))
