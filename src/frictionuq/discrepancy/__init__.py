"""The discrepancy workflow: residual diagnostics, effect screening, naming (issue 5)."""
from .diagnostics import EXPECTED_SIGNATURES, VIEW_ORDER, diagnose
from .nullperm import autocorrelation_length, block_permutation
from .features import FEATURE_UNITS, dissipated_energy, features, reversal_state
from .plots import build_figure, residual_figure

__all__ = ["EXPECTED_SIGNATURES", "FEATURE_UNITS", "VIEW_ORDER", "autocorrelation_length", "block_permutation",
           "build_figure", "diagnose", "dissipated_energy", "features", "residual_figure", "reversal_state"]
