# Sourced by the CLI tests (after setting bin to the rths binary): a scratch folder removed on
# exit, failure counting, and the check that bad input is refused. Kept out of tests/cli/*.sh,
# which CMake registers as tests one by one.
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
fail() { echo "FAIL $*"; failures=$((failures + 1)); }

# refused COMMAND NAME REGEX ARGS...: `rths COMMAND ARGS --out DIR` must exit 2, print a message
# matching REGEX on stderr, and leave no DIR behind.
refused() {
    local cmd=$1 name=$2 re=$3
    shift 3
    local o="$work/bad_$RANDOM"
    "$bin" "$cmd" "$@" --out "$o" >"$work/bstdout" 2>"$work/bstderr"
    local rc=$?
    [ "$rc" -eq 2 ] || { fail "$name: exit $rc, expected 2"; cat "$work/bstderr"; return; }
    grep -Eq -- "$re" "$work/bstderr" || { fail "$name: message /$re/ not in: $(cat "$work/bstderr")"; return; }
    [ -e "$o" ] && { fail "$name: $o was created"; return; }
    echo "ok   $name: $(head -n 1 "$work/bstderr")"
}
