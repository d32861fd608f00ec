"""Write ``pairs.csv``: 100 noisy motion pairs of a known extrinsic (the paper's random scenario,
σr = 0.57°, σt = 1 cm, appendix D.2), and ``pairs_truth.yaml`` with that extrinsic.

Run from the repository root: ``python sample_data/make_pairs.py``.
"""
from pathlib import Path

import numpy as np

from handeye_cli.geometry import se3
from handeye_cli.io.pairfile import write_pairs_csv
from handeye_cli.output.document import render
from handeye_cli.simulation import motion_pairs

HERE = Path(__file__).parent

rng = np.random.default_rng(2024)
X = se3.from_xyz_quat(np.array([0.12, -0.05, 0.21]), np.array([0.1, -0.2, 0.3, 0.9]))
A, B = motion_pairs(100, X, rng, "random", np.deg2rad(0.57), 0.01)
write_pairs_csv(HERE / "pairs.csv", A, B)
t, q = se3.to_xyz_quat(X)
(HERE / "pairs_truth.yaml").write_text(render({"matrix": X.tolist(), "translation": t.tolist(),
                                               "quaternion_xyzw": q.tolist()}))
