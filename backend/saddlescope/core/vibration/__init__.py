"""Whole-body vibration of the saddle and the rider comfort indicators (thesis chapters 7-8)."""

from saddlescope.core.vibration.indicators import *  # noqa: F403
from saddlescope.core.vibration.indicators import __all__ as _indicators_all
from saddlescope.core.vibration.weighting import *  # noqa: F403
from saddlescope.core.vibration.weighting import __all__ as _weighting_all

__all__ = [*_weighting_all, *_indicators_all]
