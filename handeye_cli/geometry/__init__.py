"""Geometry, the bottom floor every other layer may import: rigid transforms as 4x4 matrices
(:mod:`.se3`), quaternions and dual quaternions (:mod:`.dualquat`) and the Lie-group helpers of the
error analysis (:mod:`.lie`).

Conventions: ``T_a_b`` is the pose of frame b in frame a (maps points from b to a); quaternions are
Hamilton, x-y-z-w; metres and radians. Nothing here imports another part of handeye.
"""
