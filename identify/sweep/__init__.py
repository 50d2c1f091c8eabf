"""Slip sweeps: tractive force or drawbar pull against slip, and the engines that fit them.

Modules: :mod:`.problem` (validated arrays, weights, scaling), :mod:`.model` (the observation
model with effects), :mod:`.start` (where the solvers start), :mod:`.ipopt` (bounded IPOPT, the
default), :mod:`.compiled_lm` (bounded Levenberg-Marquardt as one compiled CasADi call),
:mod:`.joint` (soil and effects together), :mod:`.seed_methods` (the seed paper's Newton-Raphson
and least squares), :mod:`.slip_noise` (slip measured with noise), :mod:`.plausibility` (wrong data
must not pass as success), :mod:`.rig` (rig columns: weights, the load, repeats) and
:mod:`.sinkage_channel` (the measured sinkage against the Bekker and slip-sinkage laws),
:mod:`.likelihood` (profile likelihood of one parameter, re-optimising the others).
"""

from .problem import FitFailed, SlipProblem, make_problem

__all__ = ["FitFailed", "SlipProblem", "make_problem"]
