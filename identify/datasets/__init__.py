"""Several data sets on one soil: the joint fit and its consistency test (:func:`fit_datasets`)."""

from .fit import fit_datasets
from .result import JointFitResult

__all__ = ["fit_datasets", "JointFitResult"]
