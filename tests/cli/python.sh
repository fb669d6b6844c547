#!/usr/bin/env bash
# The Python package (python/rths) over librths, run with Debian's python3, numpy and h5py
# (tools/debian-packages.txt): every tests/python/test_*.py, against the CLI built beside librths.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
python=/usr/bin/python3 # Debian's, with python3-numpy and python3-h5py; not a pyenv shim on PATH
lib="$(cd "$(dirname "$bin")" && pwd)/librths.so"
[ -e "$lib" ] || { echo "FAIL no $lib"; exit 1; }
"$python" -c 'import numpy, h5py' || { echo "FAIL $python lacks numpy or h5py (make deps)"; exit 1; }
# An ASan build's librths needs the ASan runtime loaded first; python itself leaks by design.
asan=$(ldd "$lib" | sed -n 's/.*libasan[^ ]* => \([^ ]*\).*/\1/p' | head -n 1)
if [ -n "$asan" ]; then
    export LD_PRELOAD="$asan" ASAN_OPTIONS="detect_leaks=0${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
fi
export RTHS_LIBRARY="$lib" RTHS_BIN="$bin" RTHS_SOURCE_DIR="$src" RTHS_SCRATCH="$work"
export PYTHONPATH="$src/python" OPENBLAS_NUM_THREADS=1
for t in "$src"/tests/python/test_*.py; do
    "$python" "$t" -v 2>&1 || fail "$(basename "$t")"
done
[ "$failures" -eq 0 ] || { echo "$failures python test file(s) failed"; exit 1; }
echo "all python tests passed"
