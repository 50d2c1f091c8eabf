"""The sim-to-real gap diagnosis: where model and data part, and which explanation fits.

Entry point :func:`diagnose` (module :mod:`.diagnose`), result :class:`Diagnosis`, figure
:func:`plot_diagnosis`.
"""

from .diagnose import Diagnosis, diagnose
from .plot import plot_diagnosis

__all__ = ["diagnose", "Diagnosis", "plot_diagnosis"]
