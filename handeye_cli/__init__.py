"""handeye: the extrinsic ``T_a_b`` between two rigidly attached pose sources.

Public API::

    handeye_cli.solve(motions_a, motions_b, method="dqopt", alpha=1.0, prior=None, weights=None)
    handeye_cli.calibrate(stream_a, stream_b, config=None)          # two PoseStreams → Calibration
    handeye_cli.calibrate_files(StreamSpec(path, topic=...), StreamSpec(...), config=None)
    handeye_cli.load_config(path=None, overrides=None)               # defaults < file < overrides

Conventions: ``T_a_b`` is the pose of frame b in frame a (maps points from b to a);
quaternions are x-y-z-w; time is int64 nanoseconds; metres and radians.
"""
__version__ = "0.1.0"

from .config import load_config
from .errors import HandEyeError
from .pipeline import Calibration, StreamSpec, calibrate, calibrate_files
from .solvers import METHODS, Prior, Solution, solve
from .streams import PoseStream

__all__ = ["HandEyeError", "METHODS", "PoseStream", "Prior", "Solution", "solve", "Calibration", "StreamSpec",
           "calibrate", "calibrate_files", "load_config", "__version__"]
