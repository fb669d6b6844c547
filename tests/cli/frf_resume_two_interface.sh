#!/usr/bin/env bash
# --resume with two interface DoFs (examples/two_interface_storeys.yaml, noise off): a run stopped
# after 8 points (continuation.max_points) and resumed to the end keeps the journaled points and
# continues as an uninterrupted run: the same points and evaluations, and every interface DoF's
# amplitude within 5e-4 of it (either run lies within 2e-4 of the analytic FRF; the resumed rig
# starts from rest, so its transients differ: measured 1.9e-4).
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"
cfg="$src/examples/two_interface_storeys.yaml"
opts=(--quiet --set rig.noise=false)

"$bin" frf "$cfg" --out "$work/full" "${opts[@]}" || fail "uninterrupted run exited $?"
"$bin" frf "$cfg" --out "$work/run" "${opts[@]}" --set continuation.max_points=8 ||
    fail "first part exited $?"
"$bin" frf "$cfg" --out "$work/run" "${opts[@]}" --resume || fail "--resume exited $?"
grep -q '"resumed_points": *8' "$work/run/summary.json" || fail "summary.json does not report 8 resumed points"
python3 - "$work/full/frf.csv" "$work/run/frf.csv" <<'PY' || fail "resumed curve differs"
import csv, sys
full, run = (list(csv.DictReader(open(p))) for p in sys.argv[1:3])
worst = max(abs(float(b[f"dof{d}_amplitude_m"]) / float(a[f"dof{d}_amplitude_m"]) - 1)
            for a, b in zip(full, run) for d in (1, 2))
same = len(full) == len(run) and all(a["evaluations"] == b["evaluations"] for a, b in zip(full, run))
print(f"{len(run)} points ({len(full)} uninterrupted), worst DoF amplitude {worst:.2e} off")
sys.exit(0 if same and worst < 5e-4 else 1)
PY

[ "$failures" -eq 0 ] && echo "frf_resume_two_interface: all checks passed" || { echo "frf_resume_two_interface: $failures failure(s)"; exit 1; }
