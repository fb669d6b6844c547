#!/usr/bin/env bash
# Journal formats (docs/journal.md): a format-2 journal (the corrector's numbers as flat fields of
# each point, as rths wrote before format 3) still resumes, to the same frequencies as the
# uninterrupted run, and is rewritten in format 3; an unknown format is refused with exit 2 and a
# message naming the formats this rths reads.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
cfg="$src/examples/four_storey_linear.yaml"
opts=(--quiet --set rig.noise=false --set continuation.start_hz=12.6 --set continuation.end_hz=12.9)

"$bin" frf "$cfg" --out "$work/full" "${opts[@]}" || fail "reference run failed"
head -n 1 "$work/full/journal.jsonl" | grep -q '"format":3' || fail "new journals are not format 3"

# the first three points of the reference as a format-2 journal
mkdir -p "$work/old"
cp "$work/full/config.yaml" "$work/old/"
python3 - "$work/full/journal.jsonl" "$work/old/journal.jsonl" <<'PY'
import json, sys
H = 12  # the history ring; L = 2 * RTHS_MAX_HARMONICS + 1 and W = L - 1 follow from the length
def sizes(n):
    for L in range(3, 64):
        if 4 + 2 * L * L + 2 * L + 3 + H * (1 + 3 * (L - 1)) == n:
            return L, L - 1
    raise SystemExit("corrector_state of unexpected length %d" % n)
out = open(sys.argv[2], "w")
for n, line in enumerate(open(sys.argv[1])):
    r = json.loads(line)
    if r["type"] == "header":
        r["format"] = 2
    elif r["type"] == "point":
        if r["index"] >= 3:
            continue
        d = r.pop("corrector_state")
        L, W = sizes(len(d))
        r.pop("corrector_format")
        r["have_jacobian"], r["lti"] = int(d[0]), int(d[1])
        o = 4
        r["jacobian"] = d[o:o + L * L]; o += L * L
        r["response_jacobian"] = d[o:o + L * L]; o += L * L
        r["noise_ss_phys"] = d[o:o + L]; o += L
        r["noise_ss_num"] = d[o:o + L]; o += L
        r["noise_dof"] = d[o]; o += 1
        r["history_count"], r["history_next"] = int(d[o]), int(d[o + 1]); o += 2
        ring = [d[o + e * (1 + 3 * W):o + (e + 1) * (1 + 3 * W)] for e in range(H)]
        r["history_omega_rad_s"] = [e[0] for e in ring]
        r["history_target_m"] = [x for e in ring for x in e[1:1 + W]]
        r["history_phi_m"] = [x for e in ring for x in e[1 + W:1 + 2 * W]]
        r["history_response_m"] = [x for e in ring for x in e[1 + 2 * W:1 + 3 * W]]
    else:
        continue
    out.write(json.dumps(r) + "\n")
PY
"$bin" frf "$cfg" --out "$work/old" --resume "${opts[@]}" || fail "a format-2 journal did not resume"
head -n 1 "$work/old/journal.jsonl" | grep -q '"format":3' || fail "the resumed journal is not format 3"
grep -q '"resumed_points": *3' "$work/old/summary.json" || fail "summary does not report 3 resumed points"
# the same frequencies as the uninterrupted run (noise off: the same steps; the resumed step is
# recomputed from the last two frequencies, which rounds in the last bits) and amplitudes within
# the corrector's tolerance (1e-4 relative)
paste -d, <(cut -d, -f2,3 "$work/full/frf.csv") <(cut -d, -f2,3 "$work/old/frf.csv") | awk -F, '
    NR > 1 { if (($1 - $3)^2 > 1e-18 || ($2 - $4)^2 > (1e-4 * $2)^2) { print "row " NR ": " $0; bad = 1 } }
    END { if (NR < 5) bad = 1; exit bad }' || fail "resumed points differ from the uninterrupted run's"

# an unknown format is refused, naming the formats read
mkdir -p "$work/future"
cp "$work/full/config.yaml" "$work/future/"
sed '1s/"format":3/"format":9/' "$work/full/journal.jsonl" >"$work/future/journal.jsonl"
"$bin" frf "$cfg" --out "$work/future" --resume "${opts[@]}" 2>"$work/err"
rc=$?
[ "$rc" -eq 2 ] || fail "format 9 accepted (exit $rc)"
grep -q "journal format 9, this rths reads formats 2 and 3" "$work/err" || fail "message: $(cat "$work/err")"
[ -e "$work/future/frf.csv" ] && fail "a refused resume wrote frf.csv"
[ "$failures" -eq 0 ] && echo ok
exit "$failures"
