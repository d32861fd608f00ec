"""handeye: optimal hand-eye / extrinsic calibration from recorded pose logs."""
from __future__ import annotations

__version__ = "0.1.0"
