#!/usr/bin/env bash
# results.mat that cannot be written (issue 24, item 9): under a file size limit (`ulimit -f`)
# that every other output fits in, `rths model` exits 1 with one error line naming results.mat and
# the operating system's reason, prints none of HDF5's diagnostics, leaves no temporary file, and
# its other outputs are the same bytes as an unlimited run's. Before: SIGXFSZ killed the run (exit
# 153) and left results.mat.tmp.PID; on a full disk HDF5 printed thousands of lines and crashed at
# exit (139).
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
cfg="$src/examples/four_storey.yaml"
small=(--set model.frf.points=20)
# A gnuplot that draws nothing: its PNG (about 110 kB) would be the largest file, and gnuplot is
# not what this test is about; results.mat (about 36 kB) is then the largest by far.
mkdir -p "$work/stub"
printf '#!/bin/sh\nexit 0\n' >"$work/stub/gnuplot"
chmod +x "$work/stub/gnuplot"
export PATH="$work/stub:$PATH"

ref="$work/ref"
"$bin" model "$cfg" --out "$ref" --quiet "${small[@]}" 2>"$work/ref_stderr" ||
    fail "reference run: $(cat "$work/ref_stderr")"
mat_kb=$(( $(stat -c %s "$ref/results.mat") / 1024 ))
largest_other_kb=$(( $(find "$ref" -type f ! -name results.mat -printf '%s\n' | sort -n | tail -n 1) / 1024 + 1 ))
# a limit between the largest other file and results.mat (bash counts -f in 1024-byte blocks)
limit=$(( (largest_other_kb + mat_kb) / 2 ))
[ "$limit" -gt "$largest_other_kb" ] && [ "$limit" -lt "$mat_kb" ] ||
    fail "no room for a limit: other files up to $largest_other_kb kB, results.mat $mat_kb kB"

out="$work/limited"
( ulimit -f "$limit"; exec "$bin" model "$cfg" --out "$out" --quiet "${small[@]}" ) \
    >"$work/stdout" 2>"$work/stderr"
rc=$?
[ "$rc" -eq 1 ] || fail "exit $rc under ulimit -f $limit, expected 1"
grep -q "^rths model: cannot write $out/results.mat: File too large$" "$work/stderr" ||
    fail "no error line naming results.mat and the reason: $(cat "$work/stderr")"
[ "$(grep -c "^rths model:" "$work/stderr")" -eq 1 ] || fail "error printed more than once"
grep -q "HDF5" "$work/stderr" && fail "HDF5's diagnostics reached stderr"
# one line: the close does not retry the failed write with a second warning
[ "$(wc -l <"$work/stderr")" -eq 1 ] || fail "$(wc -l <"$work/stderr") lines on stderr"
ls -a "$out" | grep -q "tmp" && fail "temporary file left: $(ls -a "$out")"
[ -e "$out/results.mat" ] && fail "results.mat exists"
for f in modes.csv true_frf.csv config.yaml true_frf.gp; do
    cmp -s "$ref/$f" "$out/$f" || fail "$f differs from the unlimited run's"
done
[ -s "$out/summary.json" ] || fail "summary.json missing"
grep -q "finished with status 1: cannot write $out/results.mat: File too large" "$out/run.log" ||
    fail "run.log does not say why: $(tail -n 2 "$out/run.log")"
[ "$failures" -eq 0 ] && echo "ok   ulimit -f $limit: exit 1, $(head -n 1 "$work/stderr")"

[ "$failures" -eq 0 ] || { echo "$failures failure(s)"; exit 1; }
echo "results.mat failures: all checks passed"
