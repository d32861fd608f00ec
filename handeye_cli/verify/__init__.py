"""Whether a calibration may leave with exit 0: the reading of the streams decided from the data
(:mod:`.reading`), the checks of the solved result as findings (:mod:`.findings`), and the one policy that turns
them into accept, warn, retry or refuse (:mod:`.policy`, which alone answers "when does handeye refuse?").

The run (:mod:`handeye_cli.calibration.run`) reads::

    reading  = decide_reading(stream_a, stream_b, options)   # order, inversion, scale, clock offset; its pairs
    ...solve, analyse...                                      # findings from the checks of verify.findings
    outcome  = policy(findings, accept_poor_fit=…, robust=…)  # Outcome: error | retry | accepted, warnings
"""
