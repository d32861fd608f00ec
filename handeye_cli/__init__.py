"""handeye: the extrinsic ``T_a_b`` between two rigidly attached pose sources.

Public API::

    handeye_cli.solve(motions_a, motions_b, method="dqopt", alpha=1.0, prior=None, weights=None)

Conventions: ``T_a_b`` is the pose of frame b in frame a (maps points from b to a);
quaternions are x-y-z-w; time is int64 nanoseconds; metres and radians.
"""
__version__ = "0.1.0"

from .errors import HandEyeError  # noqa: E402  (after __version__, which submodules import)
from .solvers import METHODS, Prior, Solution, solve  # noqa: E402
from .streams import PoseStream  # noqa: E402

__all__ = ["HandEyeError", "METHODS", "PoseStream", "Prior", "Solution", "solve", "__version__"]
