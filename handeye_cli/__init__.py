"""handeye: the extrinsic ``T_a_b`` between two rigidly attached pose sources.

Public API::

    handeye_cli.solve(motions_a, motions_b, method="dqopt", alpha=1.0, prior=None, weights=None)
    handeye_cli.calibrate_files("a.tum", "b.tum", method="dqopt")     # files (or StreamSpec/PoseStream)
    handeye_cli.calibrate_files("log.mcap", topic_a="/cam0/pose", topic_b="/cam1/pose", alpha="auto")
    handeye_cli.calibrate(stream_a, stream_b, max_jump="off")          # two PoseStreams → Calibration
    handeye_cli.load_options(config_file=None, preset=None, **options) # defaults < preset < file < keywords

Keyword options have the command line's names without dashes (``--max-jump`` → ``max_jump``);
see :mod:`handeye_cli.options`.

Conventions: ``T_a_b`` is the pose of frame b in frame a (maps points from b to a);
quaternions are x-y-z-w; time is int64 nanoseconds; metres and radians.
"""
__version__ = "0.1.0"

from .config import load_options
from .errors import HandEyeError
from .options import Options
from .pipeline import Calibration, StreamSpec, calibrate, calibrate_files
from .solvers import METHODS, Prior, Solution, solve
from .streams import PoseStream

__all__ = ["HandEyeError", "METHODS", "PoseStream", "Prior", "Solution", "solve", "Calibration", "StreamSpec",
           "calibrate", "calibrate_files", "load_options", "Options", "__version__"]
