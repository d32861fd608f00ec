"""Small numerical routines the stages and the analysis share, written here so that a default run
imports no ``scipy.optimize``: Brent's bounded minimiser (:mod:`.minimize`) and non-negative least
squares (:mod:`.nnls`), and ``handeye rig`` no ``scipy.special``: the χ² survival function
(:mod:`.chi2`). Each is tested against scipy's, its reference. Nothing here imports another part of
handeye.
"""
