#!/bin/bash
# Includes point downward only. The module order is the ```layers block of docs/architecture.md
# (top to bottom: "module: headers of include/rths/ that belong to it"). Every src/<module>/*.[ch]
# and include/rths/*.h may include headers of its own module or of modules below it; an include
# of a module above, of a header the table does not list, or a file in a folder the table does
# not list fails, named FILE:LINE. The host (src/iterate, src/continuation, src/rig/rig_remote.c)
# must also not reach plant.h through any chain of includes (gcc -MM), which the per-file rule
# alone cannot see (rig.h may legally include plant.h; the host would then compile against it).
#
# One front door (issue 28): a command (src/cli/*.c) includes, of the project's headers, only
# rths/rths.h (the C API) and the CLI's own headers (cli/*.h); the work lives behind the API. The
# CLI's headers (src/cli/*.h) likewise include only rths/rths.h and each other, so no command
# reaches a module's header through them. CLI_PENDING below lists the files not moved behind it
# yet, with the headers each still includes: any other include fails, and so does an entry no
# longer needed (the list only shrinks).
#
# Usage: layering.sh RTHS_BIN SOURCE_DIR   (as ctest runs it: self-test, then the real tree)
#        layering.sh --check TREE          (check one tree; exit 1 on a violation)
set -u

# "FILE HEADER" pairs: CLI files that still include a header other than rths/rths.h and cli/*.h.
# Remove a pair when its file goes through the API.
CLI_PENDING="
"

# check_cli TREE PENDING: the front-door rule for TREE/src/cli/*.[ch]; prints every violation,
# returns 1 if there was one.
check_cli() {
    local tree=$1 pending=$2 status=0 f line inc n used="" what
    for f in $(cd "$tree" && ls src/cli/*.c src/cli/*.h 2>/dev/null); do
        what="a command"
        [[ $f == *.h ]] && what="a CLI header"
        n=0
        while IFS= read -r line; do
            n=$((n + 1))
            [[ $line =~ ^[[:space:]]*#[[:space:]]*include[[:space:]]*\"([^\"]*)\" ]] || continue
            inc=${BASH_REMATCH[1]}
            case $inc in rths/rths.h | cli/*.h) continue ;; esac
            if printf '%s\n' "$pending" | grep -qxF "$f $inc"; then
                used+="$f $inc"$'\n'
                continue
            fi
            echo "$f:$n: includes $inc; $what includes only rths/rths.h and the CLI's headers (cli/*.h): move what it needs behind the C API"
            status=1
        done <"$tree/$f"
    done
    local entry
    while IFS= read -r entry; do
        [ -n "$entry" ] || continue
        [ -e "$tree/${entry%% *}" ] || continue # a pending file of another tree
        printf '%s' "$used" | grep -qxF "$entry" && continue
        echo "tests/cli/layering.sh: CLI_PENDING lists '$entry', which is no longer included: remove it"
        status=1
    done <<<"$pending"
    return $status
}

# check_tree TREE: prints every violation, returns 1 if there was one.
check_tree() {
    local tree=$1 doc="$1/docs/architecture.md"
    [ -f "$doc" ] || {
        echo "$doc: missing (the module order lives there)"
        return 1
    }
    local table
    table=$(awk '/^```layers/ { on = 1; next } on && /^```/ { exit } on' "$doc")
    [ -n "$table" ] || {
        echo "$doc: no \`\`\`layers block"
        return 1
    }
    local status=0 files
    files=$(cd "$tree" && find src include/rths -type f \( -name '*.c' -o -name '*.h' \) 2>/dev/null | sort)
    # One awk pass over all files: FILENAME gives the file, FNR the line.
    (cd "$tree" && printf '%s\n' "$table" | awk -v files="$files" '
        BEGIN { n_files = split(files, list, "\n") }
        NR == FNR {
            # the table: rank 0 is the top module
            split($0, parts, ":")
            mod = parts[1]; gsub(/[ \t]/, "", mod)
            if (mod == "") next
            rank[mod] = n_mod++
            m = split(parts[2], hs, " ")
            for (i = 1; i <= m; i++) owner[hs[i]] = mod
            next
        }
        FNR == 1 {
            file = FILENAME; self = ""
            if (file ~ /^src\//) {
                split(file, p, "/"); self = p[2]
                if (!(self in rank)) {
                    printf "%s: folder src/%s is not a module of docs/architecture.md\n", file, self
                    bad = 1; self = ""
                }
            } else {
                h = file; sub(/^include\/rths\//, "", h)
                if (h in owner) self = owner[h]
                else {
                    printf "%s: header not listed in docs/architecture.md'"'"'s layers block\n", file
                    bad = 1
                }
            }
        }
        self != "" && /^[ \t]*#[ \t]*include[ \t]*"/ {
            inc = $0; sub(/^[^"]*"/, "", inc); sub(/".*/, "", inc)
            target = ""
            if (inc ~ /^rths\//) {
                h = inc; sub(/^rths\//, "", h)
                if (!(h in owner)) {
                    printf "%s:%d: includes %s, a header not listed in docs/architecture.md\n", FILENAME, FNR, inc
                    bad = 1; next
                }
                target = owner[h]
            } else if (split(inc, q, "/") > 1 && (q[1] in rank)) {
                target = q[1]
            } else next   # a sibling private header ("x.h" next to the file): its own module
            if (rank[target] < rank[self]) {
                printf "%s:%d: module %s includes %s of module %s, which is above it\n", FILENAME, FNR, self, inc, target
                bad = 1
            }
        }
        END { exit bad }
    ' - $(printf '%s\n' "$files")) || status=1
    # The host never compiles against the plant, through any chain of includes.
    local f
    for f in $(cd "$tree" && ls src/iterate/*.c src/continuation/*.c src/rig/rig_remote.c 2>/dev/null); do
        local deps
        if ! deps=$(cd "$tree" && gcc -MM -D_GNU_SOURCE -Iinclude -Isrc "$f" 2>&1); then
            echo "$f: gcc -MM failed: $deps"
            status=1
            continue
        fi
        if printf '%s\n' "$deps" | tr ' \\' '\n\n' | grep -q '/plant\.h$\|^plant\.h$'; then
            echo "$f: compiles against plant.h (gcc -MM): the host must see only rig.h and signals.h"
            status=1
        fi
    done
    check_cli "$tree" "${LAYERING_CLI_PENDING-$CLI_PENDING}" || status=1
    return $status
}

if [ "${1:-}" = "--check" ]; then
    check_tree "$2"
    exit $?
fi

SRC=$2
fail() {
    echo "FAIL: $*"
    exit 1
}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Self-test: a small tree laid out like the repository, first clean, then with violations the
# check must report at their exact lines.
make_tree() {
    rm -rf "$tmp/t"
    mkdir -p "$tmp/t/docs" "$tmp/t/include/rths" "$tmp/t/src/model" "$tmp/t/src/iterate" \
        "$tmp/t/src/rig" "$tmp/t/src/plant" "$tmp/t/src/cli"
    printf '# t\n\n```layers\ncli: \napi: rths.h\niterate: iterate.h\nrig: rig.h\nplant: plant.h\nmodel: model.h\ncore: core.h\n```\n' \
        >"$tmp/t/docs/architecture.md"
    printf '#include "rths/core.h"\n' >"$tmp/t/include/rths/rths.h"
    printf '#include "cli/cli_common.h"\n#include "cli/commands.h"\n#include "rths/rths.h"\n\n#include <stdio.h>\nint c;\n' \
        >"$tmp/t/src/cli/cmd_one.c"
    : >"$tmp/t/src/cli/cli_common.h"
    : >"$tmp/t/src/cli/commands.h"
    printf '#include "rths/core.h"\n' >"$tmp/t/include/rths/model.h"
    printf '#include "rths/model.h"\n' >"$tmp/t/include/rths/plant.h"
    printf '#include "rths/core.h"\n' >"$tmp/t/include/rths/rig.h"
    : >"$tmp/t/include/rths/core.h"
    printf '#include "rths/rig.h"\n' >"$tmp/t/include/rths/iterate.h"
    printf '#include "rths/iterate.h"\nint x;\n' >"$tmp/t/src/iterate/iterate.c"
    printf '#include "rths/rig.h"\nint y;\n' >"$tmp/t/src/rig/rig_remote.c"
    printf '#include <stdio.h>\n#include "rths/model.h"\nint z;\n' >"$tmp/t/src/model/model.c"
    printf '#include "rths/plant.h"\n#include "plant_private.h"\n' >"$tmp/t/src/plant/plant.c"
    : >"$tmp/t/src/plant/plant_private.h"
}
make_tree
bash "$0" --check "$tmp/t" >"$tmp/clean.out" 2>&1 || fail "self-test: a clean tree was refused: $(cat "$tmp/clean.out")"

make_tree # a command reaching past the C API to a module's header (legal by module order)
printf '#include "cli/cli_common.h"\n#include "rths/rths.h"\n#include "rths/model.h"\n' >"$tmp/t/src/cli/cmd_one.c"
bash "$0" --check "$tmp/t" >"$tmp/door.out" 2>&1 && fail "self-test: a command including rths/model.h passed"
grep -q "^src/cli/cmd_one.c:3: includes rths/model.h; a command includes only rths/rths.h" "$tmp/door.out" ||
    fail "self-test: the front-door violation is not named at src/cli/cmd_one.c:3: $(cat "$tmp/door.out")"
# the same include listed as pending passes; a pending entry no longer used fails
LAYERING_CLI_PENDING="src/cli/cmd_one.c rths/model.h" bash "$0" --check "$tmp/t" >"$tmp/pend.out" 2>&1 ||
    fail "self-test: a pending include was refused: $(cat "$tmp/pend.out")"
make_tree
LAYERING_CLI_PENDING="src/cli/cmd_one.c rths/model.h" bash "$0" --check "$tmp/t" >"$tmp/stale.out" 2>&1 &&
    fail "self-test: a stale CLI_PENDING entry passed"
grep -q "CLI_PENDING lists 'src/cli/cmd_one.c rths/model.h', which is no longer included" "$tmp/stale.out" ||
    fail "self-test: stale entry: $(cat "$tmp/stale.out")"

make_tree # a CLI header handing the commands a module's header (the back door of cli_common.h)
printf '#include "rths/rths.h"\n#include "rths/core.h"\n\n#include <stdint.h>\n' >"$tmp/t/src/cli/cli_common.h"
bash "$0" --check "$tmp/t" >"$tmp/hdoor.out" 2>&1 && fail "self-test: a CLI header including rths/core.h passed"
grep -q "^src/cli/cli_common.h:2: includes rths/core.h; a CLI header includes only rths/rths.h" "$tmp/hdoor.out" ||
    fail "self-test: the CLI header's violation is not named at src/cli/cli_common.h:2: $(cat "$tmp/hdoor.out")"
make_tree # a CLI header including rths/rths.h, a sibling and system headers passes
printf '#include "cli/commands.h"\n#include "rths/rths.h"\n\n#include <stdint.h>\n' >"$tmp/t/src/cli/cli_common.h"
bash "$0" --check "$tmp/t" >"$tmp/hok.out" 2>&1 || fail "self-test: a clean CLI header was refused: $(cat "$tmp/hok.out")"

make_tree # a module including a header of a module above it
printf '#include <stdio.h>\n#include "rths/model.h"\n#include "rths/rig.h"\nint z;\n' >"$tmp/t/src/model/model.c"
bash "$0" --check "$tmp/t" >"$tmp/up.out" 2>&1 && fail "self-test: model including rig.h passed"
grep -q "^src/model/model.c:3: module model includes rths/rig.h of module rig" "$tmp/up.out" ||
    fail "self-test: the violation is not named at src/model/model.c:3: $(cat "$tmp/up.out")"

make_tree # the same rule for public headers
printf '#include "rths/core.h"\n#include "rths/plant.h"\n' >"$tmp/t/include/rths/model.h"
bash "$0" --check "$tmp/t" >"$tmp/hdr.out" 2>&1 && fail "self-test: model.h including plant.h passed"
grep -q "^include/rths/model.h:2: " "$tmp/hdr.out" || fail "self-test: header violation not located: $(cat "$tmp/hdr.out")"

make_tree # a header the table does not list
printf '#include "rths/nowhere.h"\n' >>"$tmp/t/src/rig/rig_remote.c"
: >"$tmp/t/include/rths/nowhere.h"
bash "$0" --check "$tmp/t" >"$tmp/unl.out" 2>&1 && fail "self-test: an unlisted header passed"
grep -q "^src/rig/rig_remote.c:3: includes rths/nowhere.h" "$tmp/unl.out" || fail "self-test: unlisted header: $(cat "$tmp/unl.out")"

make_tree # legal per file (rig above plant), but the host now compiles against plant.h
printf '#include "rths/core.h"\n#include "rths/plant.h"\n' >"$tmp/t/include/rths/rig.h"
bash "$0" --check "$tmp/t" >"$tmp/mm.out" 2>&1 && fail "self-test: the host reaching plant.h passed"
grep -q "^src/iterate/iterate.c: compiles against plant.h" "$tmp/mm.out" || fail "self-test: gcc -MM: $(cat "$tmp/mm.out")"
grep -q "^src/rig/rig_remote.c: compiles against plant.h" "$tmp/mm.out" || fail "self-test: gcc -MM rig_remote: $(cat "$tmp/mm.out")"

# The repository itself.
bash "$0" --check "$SRC" || fail "includes do not follow docs/architecture.md's module order (above)"
echo "ok"
