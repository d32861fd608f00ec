"""handeye: the extrinsic ``T_a_b`` between two rigidly attached pose sources.

Public API::

    handeye_cli.solve(motions_a, motions_b, method="dqopt", alpha="auto", prior=None, weights=None)
    handeye_cli.solve_pairs(motions_a, motions_b, robust=True, bootstrap=200)  # handeye solve --robust --bootstrap
    handeye_cli.calibrate_files("a.tum", "b.tum", method="dqopt")     # files (or StreamSpec/PoseStream)
    handeye_cli.calibrate_files("log.mcap", stream_a="/cam0/pose", stream_b="tf:odom,imu_link", alpha="auto")
    handeye_cli.calibrate(stream_a, stream_b, gate="off")              # two PoseStreams → Calibration
    handeye_cli.load_options(config_file=None, preset=None, **options) # defaults < preset < file < keywords
    handeye_cli.calibrate_rig_files("log.mcap", ["cam0=/cam0/pose", "imu=tf:odom,imu_link"], RigOptions())
    handeye_cli.document(calibration)                                  # the result as the CLI prints it
    handeye_cli.compare_methods(calibration)                           # every method on its pairs

Keyword options have the command line's names without dashes (``--max-jump`` → ``max_jump``);
see :mod:`handeye_cli.options`. A stream is named as every command names one (``--stream-a SOURCE``,
``--stream NAME=SOURCE``): ``/topic``, ``tf:PARENT,CHILD`` or ``FILE`` (:mod:`handeye_cli.io.spec`).

Conventions: ``T_a_b`` is the pose of frame b in frame a (maps points from b to a);
quaternions are x-y-z-w; time is int64 nanoseconds; metres and radians.
"""
from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from .version import __version__

if TYPE_CHECKING:
    from .analysis.motions import PairsSolution, solve, solve_pairs
    from .calibration import Calibration, StreamSpec, calibrate, calibrate_files
    from .comparison import MethodResult, compare_methods
    from .config import load_options
    from .errors import HandEyeError
    from .options import Options
    from .rig import RigOptions, RigResult, calibrate_rig, calibrate_rig_files
    from .solvers import METHODS, Prior, Solution
    from .streams import PoseStream

# the public names and their modules, imported on first use (PEP 562): a command imports only
# the stages it runs, so ``handeye calibrate`` does not pay for the rig, the fleet or the solvers
# it does not call
_HOMES = {
    "compare_methods": "comparison", "MethodResult": "comparison",
    "load_options": "config", "HandEyeError": "errors", "Options": "options",
    "Calibration": "calibration", "StreamSpec": "calibration", "calibrate": "calibration",
    "calibrate_files": "calibration",
    "RigOptions": "rig", "RigResult": "rig", "calibrate_rig": "rig", "calibrate_rig_files": "rig",
    "METHODS": "solvers", "Prior": "solvers", "Solution": "solvers", "solve": "analysis.motions",
    "solve_pairs": "analysis.motions", "PairsSolution": "analysis.motions",
    "PoseStream": "streams",
}

__all__ = ["HandEyeError", "METHODS", "PoseStream", "Prior", "Solution", "solve", "solve_pairs", "PairsSolution",
           "Calibration", "StreamSpec",
           "calibrate", "calibrate_files", "load_options", "Options", "RigOptions", "RigResult", "calibrate_rig",
           "calibrate_rig_files", "compare_methods", "MethodResult", "document", "__version__"]


def document(result: Calibration | RigResult) -> dict[str, Any]:
    """The result document of a calibration or a rig calibration, as ``handeye calibrate`` / ``handeye
    rig`` print it (keys and units in docs/design.md: ``matrix`` is ``T_a_b``, quaternions x-y-z-w), its
    warnings naming options as keyword arguments (``max_pairs=N``), where the CLI names their flags."""
    from .calibration import Calibration
    from .errors import as_keywords, worded
    from .output.document import calibration_document

    doc = calibration_document(result) if isinstance(result, Calibration) else result.document()
    return worded(doc, as_keywords)


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        value = getattr(import_module(f".{_HOMES[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
