"""On-line identification while driving: :class:`OnlineEstimator` (moving horizon, real-time
Gauss-Newton iterations, change-of-terrain detection), its :class:`OnlineSettings` and the
:class:`OnlineEstimate` each update gives."""

from .estimator import OnlineEstimator
from .result import NOT_SEPARABLE, OnlineEstimate
from .settings import OnlineSettings

__all__ = ["OnlineEstimator", "OnlineEstimate", "OnlineSettings", "NOT_SEPARABLE"]
