#!/usr/bin/env bash
# rths controller without --site serves the whole test (site 0): the option's value was left
# uninitialised when --site was absent, so whatever the stack held decided whether the process
# loaded "site N" of a test that has no rig.sites. Run under valgrind (memcheck), which reports the
# read of the uninitialised value deterministically: every run here must be free of such errors.
# Skipped (passes) when valgrind is not installed (make deps installs it) and on the ASan build.
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"
command -v valgrind >/dev/null || { echo "skipped: no valgrind"; exit 0; }
# memcheck cannot run a sanitizer build (its shadow memory is ASan's): the -Werror pass checks it
if ldd "$bin" 2>/dev/null | grep -q libasan; then
    echo "skipped: $bin is an ASan build"
    exit 0
fi
cfg="$src/examples/four_storey.yaml"
memcheck() {
    local name=$1
    shift
    valgrind --error-exitcode=9 --leak-check=no -q "$bin" controller "$@" >"$work/out" 2>"$work/err"
    local rc=$?
    if [ "$rc" -ne 0 ]; then
        fail "$name: exit $rc under valgrind: $(grep -m 3 -A 3 '==[0-9]*== [A-Z]' "$work/err")"
    else
        echo "ok   $name: $(head -n 1 "$work/out")"
    fi
}
memcheck "served for 0.5 s, no --site" --config "$cfg" --listen 127.0.0.1:0 --duration 0.5 \
    --set server.realtime=false --quiet
memcheck "latency test, no --site" --latency-test 0.1 --set server.realtime=false --quiet
[ "$failures" -eq 0 ] || exit 1
echo "all controller default checks passed"
