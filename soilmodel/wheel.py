"""The rigid wheel (Wong-Reece), written once as CasADi expressions: its one home.

A rigid wheel of radius r and width b at slip ``i = 1 - v / (r w)`` (0 <= i < 1, driving)
touches the soil over the arc from the entry angle theta_1 to the exit angle 0 (angles from
the vertical, positive ahead of the axle)::

    cos(theta_1) = 1 - z / r                                       (z the sinkage)
    theta_m = (c1 + c2 i) theta_1                                 (largest normal stress)
    sigma(theta) = k r^n (cos(theta) - cos(theta_1))^n            theta_m <= theta <= theta_1
    sigma(theta) = k r^n (cos(theta_1 - theta/theta_m (theta_1 - theta_m)) - cos(theta_1))^n
                                                                  0 <= theta < theta_m (mirror)
    k = k_c / b + k_phi                                           (Bekker)
    j(theta) = r_s [(theta_1 - theta) - (1 - i)(sin(theta_1) - sin(theta))]
    tau(theta) = (c + sigma tan(phi)) (1 - exp(-j / K))           (Janosi-Hanamoto)

and, as the ``slip_sinkage`` effect (0 by default: the textbook wheel), ``k`` replaced by
``k / (1 + s i)``: at a given sinkage a slipping wheel's soil carries less (it is excavated and
loosened), so at a given load the wheel sinks deeper as the slip rises. With the shear radius
``r_s = r + h`` (grouser height h; ``r_s = r`` for a smooth wheel: the
grousers move the shear surface to their tips) and, with h > 0, Bekker's side shear of the soil
between the grousers: ``tau`` with ``c (1 + 2h/b)`` and ``tan(phi) (1 + 0.64 (h/b) arccot(h/b))``
(:mod:`.grousers`; ``WheelSettings(grouser_model="shear_radius")`` leaves it out). Integrated over the arc::

    DP = r b  int_0^theta_1 (tau cos(theta) - sigma sin(theta)) dtheta     drawbar pull, N
    W  = r b  int_0^theta_1 (sigma cos(theta) + tau sin(theta)) dtheta     normal load, N
    T  = r_s^2 b int_0^theta_1 tau dtheta                                  driving torque, N m

The drawbar pull is net: the horizontal part of the normal stress is the wheel's compaction
(rolling) resistance. The integrals are fixed Gauss-Legendre quadratures on [0, theta_m] and
[theta_m, theta_1] separately (the stress has a kink at theta_m), so every derivative CasADi
takes of them is the exact derivative of the same sum. Without a measured sinkage, z is solved
from the vertical balance ``W(z) = load`` (:func:`sinkage_from_load_function`, a CasADi
rootfinder: its derivatives follow from the implicit function theorem).

The stress laws are the soil's own (:mod:`.bevameter`, their one home): the normal stress at
angle theta is Bekker's plate pressure at the local depth ``r (cos(theta) - cos(theta_1))``
with the wheel's width as the plate's, the shear stress is Janosi-Hanamoto's.

Skid (braking, down to a locked wheel): with the slip as a rig records it for skid,
``i = r w / v - 1`` in [-1, 0) (-1: locked), the rim's slip velocity ``r w - v cos(theta)``
integrated over the time a soil element spends under the rim, parametrised by the travel
(``dt = r dtheta / v``: the wheel may not turn), gives Wong's shear displacement of a skidding
wheel::

    j(theta) = r_s [(1 + i)(theta_1 - theta) - (sin(theta_1) - sin(theta))]      (i < 0)

(continuous with the driving form at i = 0; at a locked wheel ``-r_s (sin theta_1 - sin theta)``,
the distance slid since the element entered). j is negative (the shear opposes the motion) and
the shear stress is Janosi-Hanamoto's with the sign of j,
``tau = sign(j) (c + sigma tan phi)(1 - exp(-|j| / K))`` (for driving j >= 0 and nothing
changes). The normal stress keeps the Wong-Reece form with theta_m = (c1 + c2 i) theta_1 (c1 > c2
keeps it inside the arc at a locked wheel). The slip-sinkage effect uses |i|.

Bulldozing (off unless :attr:`WheelSettings.bulldozing_unit_weight` is set): a sinking wheel pushes
a wedge of soil ahead of it; Bekker's bulldozing resistance of a blade of width b at depth z (as
tabulated by Wong, Theory of Ground Vehicles, ch. 2)::

    R_b = b (0.67 c z K_pc + 0.5 z^2 gamma_s K_pgamma)
    K_pc = (N_c - tan(phi)) cos^2(phi),  K_pgamma = (2 N_gamma / tan(phi) + 1) cos^2(phi)

with the bearing-capacity factors in Vesic's closed form (N_q = e^(pi tan phi) tan^2(45 deg +
phi/2), N_c = (N_q - 1) / tan(phi), N_gamma = 2 (N_q + 1) tan(phi)) and gamma_s the soil's unit
weight (N/m^3, held); it is subtracted from the drawbar pull of every row (docs/physics.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from .bevameter import plate_pressure_expr, shear_stress_expr
from .errors import DataError
from .grousers import GROUSER_MODELS, grouser_factors_expr

__all__ = [
    "WheelSettings",
    "DEFAULT_WHEEL_SETTINGS",
    "entry_angle",
    "wheel_expr",
    "wheel_forces_function",
    "sinkage_from_load_function",
    "WHEEL_OUTPUTS",
    "WHEEL_PARAMETER_NAMES",
    "evaluate",
    "bulldozing_expr",
]

#: Bekker's closed-form wheel sinkage (the rootfinder's start) holds for n < 3; larger n are capped here.
BEKKER_START_N_MAX = 2.9
#: The rootfinder's start sinkage is capped at this fraction of the radius.
BEKKER_START_Z_MAX = 0.9
#: Names of the outputs of :func:`wheel_expr`, in order.
WHEEL_OUTPUTS = ("drawbar_pull", "normal_load", "torque")
#: The wheel model's soil parameters (SI) in the order of every parameter vector (fit, prediction):
#: c (Pa), phi (rad), K (m), k_c (N/m^(n+1)), k_phi (N/m^(n+2)), n, and the slip-sinkage coefficient s.
WHEEL_PARAMETER_NAMES = (
    "cohesion",
    "friction_angle",
    "shear_modulus",
    "bekker_kc",
    "bekker_kphi",
    "bekker_n",
    "slip_sinkage",
)


@dataclass(frozen=True)
class WheelSettings:
    """Settings of the Wong-Reece wheel model.

    Parameters
    ----------
    c1, c2
        Position of the largest normal stress ``theta_m = (c1 + c2 i) theta_1`` (Wong and
        Reece's values for sand: 0.4 and 0.15 by default; c1 > c2 keeps theta_m inside the arc
        down to a locked wheel, i = -1).
    nodes
        Gauss-Legendre nodes on each of the two arcs [0, theta_m] and [theta_m, theta_1].
        With n < 1 the stress has an integrable root singularity at theta_1; 24 nodes a side
        integrate the forces to about 1e-4 relative (checked against 200 nodes in the tests).
    """

    c1: float = 0.4
    c2: float = 0.15
    nodes: int = 24
    #: Soil unit weight gamma_s of the bulldozing resistance, N/m^3 (``None``: no bulldozing term).
    bulldozing_unit_weight: float | None = None
    #: Grousers (h > 0): ``bekker`` adds Bekker's side shear (:mod:`.grousers`) to the shear radius r + h;
    #: ``shear_radius`` is the shear radius alone (grousers then only rescale K).
    grouser_model: str = "bekker"

    def __post_init__(self) -> None:
        for name in ("c1", "c2"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise DataError(f"wheel setting {name} must be a finite number, got {v!r}")
        if not 0 < self.c1 < 1 or not 0 <= self.c1 + self.c2 < 1 or self.c2 < 0:
            raise DataError(
                f"wheel settings need 0 < c1 < 1, c2 >= 0 and c1 + c2 < 1 (theta_m inside the arc at "
                f"every slip), got c1 = {self.c1}, c2 = {self.c2}"
            )
        if isinstance(self.nodes, bool) or not isinstance(self.nodes, int) or not 2 <= self.nodes <= 400:
            raise DataError(f"wheel setting nodes must be an integer in [2, 400], got {self.nodes!r}")
        if self.grouser_model not in GROUSER_MODELS:
            raise DataError(f"wheel setting grouser_model must be one of {GROUSER_MODELS}, got {self.grouser_model!r}")
        g = self.bulldozing_unit_weight
        if g is not None and (isinstance(g, bool) or not isinstance(g, (int, float)) or not 0 < g < 1e6):
            raise DataError(f"wheel setting bulldozing_unit_weight must be a unit weight in (0, 1e6) N/m^3, got {g!r}")


DEFAULT_WHEEL_SETTINGS = WheelSettings()


def entry_angle(z, r):
    """Entry angle theta_1 = acos(1 - z / r), rad (symbolic or float; z in (0, r])."""
    return ca.acos(1 - z / r)


def bulldozing_expr(z, c, phi, b, unit_weight):
    """Bekker's bulldozing resistance ``b (0.67 c z K_pc + 0.5 z^2 gamma_s K_pgamma)``, N (see the module text)."""
    t = ca.tan(phi)
    n_q = ca.exp(np.pi * t) * ca.tan(np.pi / 4 + phi / 2) ** 2
    n_c = (n_q - 1) / t
    n_g = 2 * (n_q + 1) * t
    cos2 = ca.cos(phi) ** 2
    return b * (0.67 * c * z * (n_c - t) * cos2 + 0.5 * z**2 * unit_weight * (2 * n_g / t + 1) * cos2)


def _as_column(x):
    """A CasADi column of ``x`` (floats and arrays become DM)."""
    if isinstance(x, (ca.SX, ca.MX, ca.DM)):
        return x
    return ca.DM(np.asarray(x, dtype=float).reshape(-1, 1))


def wheel_expr(
    i,
    z,
    c,
    phi,
    K,
    k_c,
    k_phi,
    n,
    r,
    b,
    h=0.0,
    settings: WheelSettings = DEFAULT_WHEEL_SETTINGS,
    slip_sinkage=0.0,
):
    """Drawbar pull, normal load and torque of the Wong-Reece rigid wheel (symbolic or numeric).

    Parameters
    ----------
    i, z
        Slip (0 <= i < 1) and sinkage (m, 0 < z <= r): columns of equal length (or scalars).
    c, phi, K
        Cohesion (Pa), friction angle (rad), shear deformation modulus (m).
    k_c, k_phi, n
        Bekker moduli (N/m^(n+1), N/m^(n+2)) and exponent n (with the wheel's width b as the
        plate's, only ``k_c / b + k_phi`` matters).
    r, b, h
        Wheel radius, width and grouser height, m.
    settings
        :class:`WheelSettings` (c1, c2, quadrature nodes).
    slip_sinkage
        Coefficient s of the slip-sinkage effect (stresses scaled by ``1 / (1 + s i)``); 0: none.

    Returns
    -------
    drawbar_pull, normal_load, torque
        Columns (N, N, N m), same type family as the inputs (DM for floats).
    """
    i, z = _as_column(i), _as_column(z)
    x, w = np.polynomial.legendre.leggauss(settings.nodes)
    xr = ca.DM((x.reshape(1, -1) + 1) / 2)  # nodes on [0, 1], row
    wc = ca.DM(w.reshape(-1, 1) / 2)  # weights on [0, 1], column
    m = max(i.shape[0], z.shape[0])
    ones = ca.DM.ones(1, settings.nodes)
    if i.shape[0] != m:
        i = ca.repmat(i, m, 1)
    if z.shape[0] != m:
        z = ca.repmat(z, m, 1)
    th1 = entry_angle(z, r)
    thm = (settings.c1 + settings.c2 * i) * th1
    rs = r + h
    cos1, sin1 = ca.cos(th1), ca.sin(th1)

    skid = ca.mtimes(i < 0, ones)  # 1 on the rows at negative slip
    c_s, phi_s = c, phi
    if settings.grouser_model == "bekker" and not (isinstance(h, (int, float)) and h == 0):
        f_c, f_phi = grouser_factors_expr(h, b)  # Bekker's side shear of the soil between the grousers
        c_s, phi_s = c * f_c, ca.atan(f_phi * ca.tan(phi))

    def integrands(theta, sigma):
        arc, chord = ca.mtimes(th1, ones) - theta, ca.mtimes(sin1, ones) - ca.sin(theta)
        j_drive = rs * (arc - ca.mtimes(1 - i, ones) * chord)
        j_skid = rs * (ca.mtimes(1 + i, ones) * arc - chord)  # Wong's skid form (module text)
        j = ca.if_else(skid, j_skid, j_drive)
        tau = ca.sign(j) * shear_stress_expr(ca.fabs(j), sigma, c_s, phi_s, K)
        return (tau * ca.cos(theta) - sigma * ca.sin(theta), sigma * ca.cos(theta) + tau * ca.sin(theta), tau)

    soften = ca.mtimes(1 / (1 + slip_sinkage * ca.fabs(i)), ones)  # the slip-sinkage effect (1 when off)

    def sigma_at(theta_eq):
        depth = r * (ca.cos(theta_eq) - ca.mtimes(cos1, ones))  # the soil's depth under the rim at theta_eq
        return soften * plate_pressure_expr(depth, b, k_c, k_phi, n, z_ref=r)

    # front arc [theta_m, theta_1]
    th_f = ca.mtimes(thm, ones) + ca.mtimes(th1 - thm, xr)
    sig_f = sigma_at(th_f)
    # rear arc [0, theta_m]: the mirror of the front arc's stress
    th_r = ca.mtimes(thm, xr)
    sig_r = sigma_at(ca.mtimes(th1, ones) - ca.mtimes(th1 - thm, xr))
    out = []
    for a_f, a_r in zip(integrands(th_f, sig_f), integrands(th_r, sig_r)):
        out.append((th1 - thm) * ca.mtimes(a_f, wc) + thm * ca.mtimes(a_r, wc))
    dp, wl, tq = out
    dp = r * b * dp
    if settings.bulldozing_unit_weight is not None:
        dp = dp - bulldozing_expr(z, c, phi, b, settings.bulldozing_unit_weight)
    return dp, r * b * wl, rs**2 * b * tq


def wheel_forces_function(
    r: float, b: float, h: float = 0.0, settings: WheelSettings = DEFAULT_WHEEL_SETTINGS
) -> ca.Function:
    """CasADi Function ``(i, z, c, phi, K, k_c, k_phi, n, s) -> (drawbar_pull, normal_load, torque)``.

    One row.

    ``s`` is the slip-sinkage coefficient (0: the textbook wheel).
    """
    names = ["i", "z", "c", "phi", "K", "k_c", "k_phi", "n", "s"]
    s = [ca.SX.sym(nm) for nm in names]
    dp, wl, tq = wheel_expr(s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], r, b, h, settings, slip_sinkage=s[8])
    return ca.Function("rigid_wheel", s, [dp, wl, tq], names, list(WHEEL_OUTPUTS))


def sinkage_from_load_function(
    r: float,
    b: float,
    h: float = 0.0,
    settings: WheelSettings = DEFAULT_WHEEL_SETTINGS,
    *,
    grouser_input: bool = False,
) -> ca.Function:
    """CasADi Function ``(i, W, c, phi, K, k_c, k_phi, n, s) -> z``: the sinkage at which the wheel carries W.

    With ``grouser_input`` the grouser height is a last input ``h`` (m; ``h`` here is then ignored): a
    fit can free it.

    Newton's method on ``log W(theta_1) = log W`` in ``u = log theta_1`` (W grows about like
    theta_1^(2n+1), so the residual is nearly linear in u), started from Bekker's closed-form
    sinkage of a wheel, ``z0 = (3 W / ((3 - n) k b sqrt(2 r)))^(2 / (2 n + 1))`` with
    ``k = k_c / b + k_phi``. Derivatives
    with respect to every input follow from the implicit function theorem.
    """
    u = ca.MX.sym("u")
    names = ["i", "W", "c", "phi", "K", "k_c", "k_phi", "n", "s"] + (["h"] if grouser_input else [])
    p = ca.MX.sym("p", len(names))
    i, W, c, phi, K, k_c, k_phi, n, s = (p[q] for q in range(9))
    height: float | ca.MX = p[9] if grouser_input else h
    th1 = ca.exp(u)
    z = r * (1 - ca.cos(th1))
    _, wl, _ = wheel_expr(i, z, c, phi, K, k_c, k_phi, n, r, b, height, settings, slip_sinkage=s)
    g = ca.Function("g", [u, p], [ca.log(wl) - ca.log(W)])
    # no eval warnings: a trial point of a fit where the wheel cannot carry the load gives NaN, which
    # IPOPT's line search handles by a shorter step
    rf = ca.rootfinder(
        "wheel_sinkage",
        "newton",
        g,
        {"abstol": 1e-12, "max_iter": 60, "error_on_fail": False, "show_eval_warnings": False},
    )
    ins = [ca.MX.sym(nm) for nm in names]
    i_, W_, c_, phi_, K_, kc_, kphi_, n_, s_ = ins[:9]
    k_eff = (kc_ / b + kphi_) / (1 + s_ * ca.fabs(i_))
    z0 = (3 * W_ / ((3 - ca.fmin(n_, BEKKER_START_N_MAX)) * k_eff * b * ca.sqrt(2 * r))) ** (2 / (2 * n_ + 1))
    u0 = ca.log(entry_angle(ca.fmin(z0, BEKKER_START_Z_MAX * r), r))
    u_star = rf(u0, ca.vertcat(*ins))
    z_star = r * (1 - ca.cos(ca.exp(u_star)))
    return ca.Function("wheel_sinkage_from_load", ins, [z_star], names, ["z"])


def evaluate(fn: ca.Function, *args: Any) -> list[np.ndarray]:
    """Evaluate a row Function of this module over arrays (broadcast), as numpy arrays."""
    arrs = np.broadcast_arrays(*[np.asarray(a, dtype=float) for a in args])
    shape = arrs[0].shape
    mapped = fn.map(int(arrs[0].size))
    out = mapped(*[ca.DM(a.reshape(1, -1)) for a in arrs])
    outs = out if isinstance(out, (list, tuple)) else [out]
    return [np.asarray(x, dtype=float).reshape(shape) for x in outs]
