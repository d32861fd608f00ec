"""Array type aliases for annotations across handeye (``numpy.typing``).

Shapes and units are not part of these types; docstrings state them (e.g. ``(N, 4, 4)`` transforms
``T_a_b`` in metres, ``(…, 4)`` quaternions in x-y-z-w order).
"""
from __future__ import annotations

from typing import TypeAlias

import numpy as np
from numpy.typing import NDArray

__all__ = ["FloatArray", "IntArray", "BoolArray"]

FloatArray: TypeAlias = NDArray[np.float64]
"""Float64 array: transforms, quaternions, residuals, covariances."""

IntArray: TypeAlias = NDArray[np.intp]
"""Platform integer array: indices and counts (what ``np.flatnonzero`` and ``np.argsort`` return)."""

BoolArray: TypeAlias = NDArray[np.bool_]
"""Boolean array: masks over pairs or samples."""
