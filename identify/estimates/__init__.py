"""What a fit says: the result record, its statistics, identifiability, intervals and report.

Modules: :mod:`.estimate` (:class:`~.estimate.Estimate`, the one record every data kind moves onto, and
its free functions: outcome, report, JSON; the bevameter tests' today), :mod:`.records` (one parameter's
estimate, one identifiable combination and the one rule of its being determined),
:mod:`.result` (:class:`FitResult` and its builders), :mod:`.least_squares` (rank, covariance,
degrees of freedom from the Jacobian), :mod:`.identifiability` (null space, the c-phi ridge),
:mod:`.views` (estimates per parameter and combination), :mod:`.report` (words and JSON; the
outcome vocabulary :data:`OUTCOMES` and the residual sign :data:`RESIDUAL_SIGN` of every output),
:mod:`.distributions` (Student t, normal, F, chi-square without scipy), :mod:`.joint_likelihood` (profile
intervals of joint fits), :mod:`.record_fields` (what the view mixins read, for the type checker). The record
knows no data kind (tested): the profile likelihood of one sweep parameter is
:mod:`soiltrack.identify.sweep.likelihood`, the plausibility checks of slip data
:mod:`soiltrack.identify.sweep.plausibility`.
"""

from .records import Combination, ParameterEstimate
from .report import OUTCOMES, RESIDUAL_SIGN
from .result import FitResult, build_result

__all__ = ["FitResult", "ParameterEstimate", "Combination", "build_result", "OUTCOMES", "RESIDUAL_SIGN"]
