#!/usr/bin/env bash
# A full disk while rths frf writes results.mat (issue 24, item 9): the run exits 1 with its
# reason in one line naming results.mat, HDF5 prints nothing, no temporary file is left, and the
# other outputs (frf.csv, summary.json, journal.jsonl) are complete. The run folder lives on a
# tmpfs, in a private mount namespace, sized so that everything but results.mat fits (results.mat
# is written last). Before: HDF5 printed thousands of lines and the process crashed at exit (139),
# or, without room, results.mat was only a warning at exit 0. Skipped (with the reason) where a
# tmpfs cannot be mounted.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
cfg="$src/examples/four_storey_linear.yaml"
run=(--set continuation.start_hz=13.4 --set continuation.end_hz=13.5 --set rig.noise=false --quiet)
# a gnuplot that draws nothing: figures are not what this test is about
mkdir -p "$work/stub"
printf '#!/bin/sh\nexit 0\n' >"$work/stub/gnuplot"
chmod +x "$work/stub/gnuplot"
export PATH="$work/stub:$PATH"
if ! unshare -m sh -c "mount -t tmpfs -o size=64k tmpfs '$work/stub' 2>/dev/null" 2>/dev/null; then
    echo "SKIP: cannot mount a tmpfs in a private mount namespace here"
    exit 0
fi
"$bin" frf "$cfg" --out "$work/ref" "${run[@]}" 2>"$work/ref.err" || fail "reference run: $(cat "$work/ref.err")"
pages() { echo $(( ($1 + 4095) / 4096 )); }
others=0
for f in "$work"/ref/* "$work"/ref/.[!.]*; do
    [ -f "$f" ] && [ "$(basename "$f")" != results.mat ] && others=$(( others + $(pages "$(stat -c %s "$f")") ))
done
mat=$(pages "$(stat -c %s "$work/ref/results.mat")")
# room for every other file (each written once: a temporary renamed onto its name) and a few
# pages of slack, plus half of results.mat
size_kb=$(( 4 * (others + 4 + mat / 2) ))
[ "$mat" -gt 16 ] || fail "results.mat of $mat pages is too small for this test"
mkdir -p "$work/fs" "$work/after"
unshare -m sh -c "mount -t tmpfs -o size=${size_kb}k tmpfs '$work/fs' || exit 99; \
    '$bin' frf '$cfg' --out '$work/fs/run' $(printf "'%s' " "${run[@]}") \
    >'$work/stdout' 2>'$work/stderr'; rc=\$?; cp -a '$work/fs/run/.' '$work/after/'; exit \$rc"
rc=$?
[ "$rc" -eq 1 ] || fail "exit $rc on a full disk, expected 1: $(cat "$work/stderr")"
grep -q "cannot write .*results.mat: No space left on device" "$work/stderr" ||
    fail "no line naming results.mat and the reason: $(cat "$work/stderr")"
grep -q "HDF5" "$work/stderr" && fail "HDF5's diagnostics reached stderr"
[ "$(grep -c "results.mat" "$work/stderr")" -eq 1 ] || fail "results.mat named more than once: $(cat "$work/stderr")"
ls -a "$work/after" | grep -q "tmp" && fail "temporary file left: $(ls -a "$work/after")"
[ -e "$work/after/results.mat" ] && fail "results.mat exists"
for f in frf.csv journal.jsonl config.yaml truth.csv; do
    cmp -s "$work/ref/$f" "$work/after/$f" || fail "$f differs from the unlimited run's"
done
[ -s "$work/after/summary.json" ] || fail "summary.json missing"
echo "full disk (tmpfs of $size_kb kB): exit $rc, $(head -c 300 "$work/stderr")"
exit $((failures > 0))
