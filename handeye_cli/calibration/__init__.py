"""One calibration of two pose streams: its inputs named and read (:mod:`.inputs`), one reading's pairs
(:mod:`.pairing`), the run in typed steps (:mod:`.run`), b's scale (:mod:`.scaling`) and the typed results
(:mod:`.result`). Whether a result may leave is decided by :mod:`handeye_cli.verify`.

The extrinsic is ``T_a_b``: the pose of sensor b's frame in sensor a's frame (maps points from b to a), where
each stream holds ``T_world_sensor(t)`` (int64 ns stamps, positions [m], quaternions x-y-z-w).

The names below are imported on first use (PEP 562): :mod:`handeye_cli.verify` sits between this package's
parts (inputs, pairing, result below it; the run above it), so importing one part must not import the run.
"""
from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..io.spec import StreamSpec
    from .inputs import (
        Inputs,
        Source,
        check_samples,
        inverted_as_read,
        read_prior,
        read_streams,
        refuse_unread,
        stream_specs,
    )
    from .pairing import Paired, pairs_of
    from .result import Calibration, Checks, Diagnostics, Uncertainty, frame_names
    from .run import calibrate, calibrate_files, calibrate_read, calibrate_specs

_HOMES = {
    "StreamSpec": "..io.spec",
    **dict.fromkeys(("Inputs", "Source", "check_samples", "inverted_as_read", "read_prior", "read_streams",
                     "refuse_unread", "stream_specs"), ".inputs"),
    **dict.fromkeys(("Paired", "pairs_of"), ".pairing"),
    **dict.fromkeys(("Calibration", "Checks", "Diagnostics", "Uncertainty", "frame_names"), ".result"),
    **dict.fromkeys(("calibrate", "calibrate_files", "calibrate_read", "calibrate_specs"), ".run"),
}

__all__ = ["Calibration", "Checks", "Diagnostics", "Inputs", "Paired", "Source", "StreamSpec", "Uncertainty",
           "calibrate", "calibrate_files", "calibrate_read", "calibrate_specs", "check_samples", "frame_names",
           "inverted_as_read", "pairs_of", "read_prior", "read_streams", "refuse_unread", "stream_specs"]


def __getattr__(name: str) -> Any:
    """The public name ``name``, imported from its module on first use."""
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_HOMES[name], __name__), name)
    globals()[name] = value
    return value
