"""The sim-to-real gap diagnosis: one comparison of hypotheses (docs/diagnosis.md).

Entry point :func:`diagnose`, result :class:`Diagnosis`, settings :class:`DiagnoseSettings`, figure
:func:`plot_diagnosis`.
"""

from .diagnose import diagnose
from .plot import plot_diagnosis
from .result import Diagnosis, RankEntry
from .settings import DiagnoseSettings

__all__ = ["diagnose", "Diagnosis", "RankEntry", "DiagnoseSettings", "plot_diagnosis"]
