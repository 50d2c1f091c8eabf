"""Traversability margins and traction planning, built on the model core and on identified soils.

Public names: :func:`margin` / :class:`Margin` (available against required thrust, with the
probability of being traversable for an identified soil), :class:`SoilUncertainty`,
:func:`uncertainty_from_fit`, :func:`load_fit_json`.
"""
from .margin import DEFAULT_MAX_SLIP, Margin, margin
from .uncertainty import SoilUncertainty, load_fit_json, uncertainty_from_fit

__all__ = ["DEFAULT_MAX_SLIP", "Margin", "margin", "SoilUncertainty", "load_fit_json", "uncertainty_from_fit"]
