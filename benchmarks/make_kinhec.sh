#!/usr/bin/env bash
# Generate kinhec sequences for benchmarks/real.py (never committed: they go to a cache outside the repo).
#
#   benchmarks/make_kinhec.sh KINHEC_EXECUTABLE [SEED ...]      (default seed: 1)
#
# KINHEC_EXECUTABLE is the `kinhec` command of a scratch environment, e.g.
#   python3 -m venv /tmp/kinhec-venv && /tmp/kinhec-venv/bin/pip install kinhec==1.1.0
#   benchmarks/make_kinhec.sh /tmp/kinhec-venv/bin/kinhec 1 2
# Per seed, into ${HANDEYE_BENCH_CACHE:-~/.cache/handeye-bench}/kinhec-SEED/:
#   data/                      `kinhec generate --tier <smoke tier with global_seed SEED>` (46 sequences, ~45 s)
#   ID_robot.tum, ID_camera.tum  what `kinhec export data ID --format tum` writes
#   ID_groundtruth.json          what `kinhec export data ID --format csv` writes beside its CSVs (CSVs dropped)
#   published.json               per ID, the published solver's X error [deg, mm]: kinhec's own protocol
#                                (benchmark.py: consecutive keyframe motions, oracle time offset) with its
#                                Park-Martin + LM, camera translations divided by the true scale first (as the
#                                smoke README's table does for monocular sequences)
# The exports run through kinhec's Python API (the functions `kinhec export` calls) in one process per
# seed, which is ~60x faster than one `kinhec export` per file.
set -euo pipefail
KINHEC=${1:?usage: make_kinhec.sh KINHEC_EXECUTABLE [SEED ...]}
shift
SEEDS=("${@:-1}")
[ ${#SEEDS[@]} -gt 0 ] || SEEDS=(1)
PY=$(head -1 "$KINHEC" | sed 's/^#!//')          # the interpreter of the kinhec entry point
CACHE=${HANDEYE_BENCH_CACHE:-$HOME/.cache/handeye-bench}
"$KINHEC" --version
for SEED in "${SEEDS[@]}"; do
  OUT=$CACHE/kinhec-$SEED
  mkdir -p "$OUT"
  TIER=$OUT/smoke-seed-$SEED.yaml
  "$PY" - "$TIER" "$SEED" <<'EOF'
import re, sys
from pathlib import Path
import kinhec
src = (Path(kinhec.__file__).parent / "configs" / "smoke.yaml").read_text()
text, n = re.subn(r"(?m)^global_seed:.*$", f"global_seed: {int(sys.argv[2])}", src)
assert n == 1, "smoke.yaml has no global_seed line"
Path(sys.argv[1]).write_text(text.replace("tier: smoke", f"tier: smoke-seed-{int(sys.argv[2])}", 1))
EOF
  [ -f "$OUT/data/sequences.csv" ] || "$KINHEC" generate --tier "$TIER" --out "$OUT/data" --workers 1 \
      --work-dir "$OUT/work" --no-card
  "$PY" - "$OUT" <<'EOF'
import json, shutil, sys, tempfile
from pathlib import Path
import numpy as np
from kinhec import solvers
from kinhec.benchmark import _keyframe_data
from kinhec.io import load_manifest, _load_from_row
from kinhec.metrics import calibration_errors

out = Path(sys.argv[1])
data = out / "data"
published = {}
rows = load_manifest(data).to_dict("records")
with tempfile.TemporaryDirectory() as tmp:
    for row in rows:
        seq = _load_from_row(data, row)
        seq.to_tum(out)                                      # = kinhec export data ID --format tum
        for p in seq.to_csv(Path(tmp)):                      # = kinhec export data ID --format csv
            if p.name.endswith("_groundtruth.json"):
                shutil.copy(p, out / p.name)
        kf = _keyframe_data(seq, None if seq.synchronous else seq.time_offset)   # oracle offset
        if kf is None:
            continue
        _, _, A, B = kf
        B = B.copy()
        B[:, :3, 3] /= seq.scale                             # metric camera translations
        try:
            X = solvers.refine_lm(A, B, solvers.park_martin(A, B))
            e = calibration_errors(X, seq.X)
            published[seq.id] = [float(e["X_rot_err_deg"]), float(e["X_trans_err_mm"])]
        except Exception as ex:                              # a solver failure is an outcome, as in kinhec
            published[seq.id] = f"{type(ex).__name__}: {ex}"
(out / "published.json").write_text(json.dumps({"solver": "park_martin+lm (kinhec 1.1.0), oracle sync, "
                                                "consecutive keyframe motions, metric camera translations",
                                                "X_error_deg_mm": published}, indent=1))
print(f"{len(rows)} sequences exported to {out}")
EOF
done
