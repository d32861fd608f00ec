"""Fleet recalibration: many inputs in one run (``handeye batch``), drift verdicts, local and Dask executors.

:mod:`.discovery` turns arguments into inputs, :mod:`.engine` calibrates them (one process, a
process pool or a Dask cluster), :mod:`.cache` keeps per-input result files for ``--skip-done``,
:mod:`.overrides` holds per-input options, :mod:`.batch` judges, orders and summarises the records.
"""
from .batch import BatchSettings, BatchSummary, run_batch
from .discovery import BatchInput, discover
from .engine import Job, Streams, run_job

__all__ = ["BatchInput", "BatchSettings", "BatchSummary", "Job", "Streams", "discover", "run_batch", "run_job"]
