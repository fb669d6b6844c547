#!/usr/bin/env bash
# Every malformed configuration in tests/data/bad_configs is refused before any work: exit status 2,
# a message matching the file's "# expect:" regex (file:line:column and the key), nothing written.
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
count=0

check() { # name, expected regex, command...
    local name=$1 expect=$2
    shift 2
    count=$((count + 1))
    local out="$work/out_$count"
    "$@" --out "$out" >"$work/stdout" 2>"$work/stderr"
    local rc=$?
    if [ "$rc" -ne 2 ]; then
        echo "FAIL $name: exit status $rc, expected 2"; cat "$work/stderr"; failures=$((failures + 1)); return
    fi
    if ! grep -Eq -- "$expect" "$work/stderr"; then
        echo "FAIL $name: message does not match /$expect/:"; cat "$work/stderr"; failures=$((failures + 1)); return
    fi
    if [ -e "$out" ]; then
        echo "FAIL $name: output folder $out was created"; failures=$((failures + 1)); return
    fi
    echo "ok   $name: $(head -c 200 "$work/stderr" | head -n 1)"
}

for f in "$src"/tests/data/bad_configs/*.yaml; do
    expect=$(sed -n '1s/^# expect: //p' "$f")
    [ -n "$expect" ] || { echo "FAIL $f has no '# expect:' line"; failures=$((failures + 1)); continue; }
    check "$(basename "$f")" "$expect" "$bin" model "$f"
done

good="$src/examples/four_storey.yaml"
check "--set out of range" "--set split.mass_ratio.*(strictly between 0 and 1|\[0, 1\]|\(0, 1\))" \
    "$bin" model "$good" --set split.mass_ratio=1.0
check "--set not a number" "--set forcing.amplitude_n.*number" "$bin" model "$good" --set forcing.amplitude_n=abc
check "--set unknown key" "unknown key 'split.colour'" "$bin" model "$good" --set split.colour=3
check "--set without =" "--set" "$bin" model "$good" --set split.mass_ratio
check "missing config file" "no_such_file.yaml" "$bin" model "$work/no_such_file.yaml"
check "unknown option" "--frobnicate" "$bin" model "$good" --frobnicate

[ "$count" -ge 15 ] || { echo "FAIL only $count cases"; failures=$((failures + 1)); }
echo "$count cases, $failures failures"
[ "$failures" -eq 0 ]
