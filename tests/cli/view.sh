#!/usr/bin/env bash
# rths view: the JSON API against a real run's files (finished, and journal-only as while the run
# is in progress), refusals (bad command lines, missing/non-run folders, path traversal, a port in
# use), a free port picked, loopback by default, a vanished folder survived; then the page in
# headless Chromium (tests/browser/view_browser.mjs: no console error, drawn points = frf.csv, a
# screenshot that is not blank, a growing run followed). Screenshots stay in view-test-output/.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
out="$PWD/view-test-output"
pids=()
trap 'for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done; rm -rf "$work"' EXIT

command -v node >/dev/null || { echo "FAIL node is missing (make deps installs nodejs)"; exit 1; }

# start_view NAME RUN_DIR [ARGS...]: starts `rths view` in the background and waits for the line
# giving its address; sets $port and $base. Returns 1 if it never served.
start_view() {
    local name=$1
    shift
    "$bin" view "$@" >"$work/$name.out" 2>"$work/$name.err" &
    pids+=($!)
    for _ in $(seq 100); do
        port=$(sed -n 's|.* at http://[^ ]*:\([0-9][0-9]*\)/ .*|\1|p' "$work/$name.out")
        [ -n "$port" ] && break
        sleep 0.1
    done
    [ -n "$port" ] || { fail "$name: no address printed: $(cat "$work/$name.err")"; return 1; }
    base="http://127.0.0.1:$port/"
}

# exit_2 NAME REGEX ARGS...: `rths view ARGS` refuses with exit 2 and a message matching REGEX.
exit_2() {
    local name=$1 re=$2
    shift 2
    timeout 10 "$bin" view "$@" >/dev/null 2>"$work/err"
    local rc=$?
    if [ $rc -eq 2 ] && grep -Eq -- "$re" "$work/err"; then echo "ok   $name: $(head -n 1 "$work/err")"
    else fail "$name: exit $rc, $(cat "$work/err")"; fi
}

# 1. a short real run
"$bin" frf "$src/examples/four_storey_linear.yaml" --out "$work/run" --quiet \
    --set continuation.start_hz=12.9 --set continuation.end_hz=13.2 || { echo "FAIL frf run"; exit 1; }
ln -s /etc/passwd "$work/run/outside_link"
echo secret >"$work/run/.hidden"
uplot=""
[ -d "$src/web/node_modules/uplot" ] && uplot=--uplot

# 2. finished run: the API equals the files; a free port was picked (port 0)
if start_view finished "$work/run" --listen 127.0.0.1:0; then
    [ "$port" -gt 0 ] && echo "ok   --listen 127.0.0.1:0 picked free port $port" || fail "port $port"
    node "$src/tests/browser/api_check.mjs" "$base" "$work/run" "$work/run/frf.csv" frf.csv $uplot ||
        fail "API of a finished run"
    # loopback only: the listening socket is bound to 127.0.0.1 (/proc/net/tcp, state 0A = LISTEN)
    hexport=$(printf '%04X' "$port")
    grep -Eq "^ *[0-9]+: 0100007F:$hexport 00000000:0000 0A" /proc/net/tcp &&
        echo "ok   bound to 127.0.0.1:$port only" || fail "not bound to loopback"
    # the same port again: cannot listen, exit 1 with a message
    timeout 10 "$bin" view "$work/run" --listen "127.0.0.1:$port" >/dev/null 2>"$work/err"
    rc=$?
    [ $rc -eq 1 ] && grep -q "cannot listen" "$work/err" && echo "ok   port in use: $(cat "$work/err")" ||
        fail "port in use: exit $rc $(cat "$work/err")"
fi

# 3. in progress: no frf.csv or summary.json yet, the points come from the journal and must
# equal what the run later writes to frf.csv
cp -r "$work/run" "$work/inprogress"
rm "$work/inprogress/frf.csv" "$work/inprogress/summary.json"
if start_view inprogress "$work/inprogress" --listen 127.0.0.1:0; then
    node "$src/tests/browser/api_check.mjs" "$base" "$work/inprogress" "$work/run/frf.csv" journal.jsonl $uplot ||
        fail "API of a run in progress"
    # the folder vanishes under the server: clear errors, no crash
    rm -rf "$work/inprogress"
    code=$(node -e "fetch('${base}api/points').then(async r => console.log(r.status, (await r.json()).error))")
    echo "$code" | grep -q "^404 .*gone" && echo "ok   vanished folder: $code" || fail "vanished folder: $code"
    node -e "fetch('${base}api/status').then(r => r.json()).then(j => process.exit(j.state === 'gone' ? 0 : 1))" &&
        echo "ok   still serving, status says gone" || fail "server died with its folder"
fi

# 4. refusals: exit 2, a message, nothing served
mkdir -p "$work/empty"
exit_2 "missing RUN_DIR" "missing RUN_DIR"
exit_2 "no such folder" "No such file or directory" "$work/nowhere"
exit_2 "a file, not a folder" "is not a folder" "$work/run/frf.csv"
exit_2 "not a run folder" "is not a run folder" "$work/empty"
exit_2 "listen without port" "expected HOST:PORT" "$work/run" --listen 127.0.0.1
exit_2 "listen port out of range" "expected HOST:PORT" "$work/run" --listen 127.0.0.1:70000
exit_2 "listen host name" "not a numeric" "$work/run" --listen example.com:80
exit_2 "unknown option" "unknown option" "$work/run" --bogus
exit_2 "two folders" "unexpected argument" "$work/run" "$work/run"
"$bin" view --help | grep -q -- "--listen ADDR:PORT" && echo "ok   --help" || fail "--help"

# 5. any address but loopback only when asked, with a warning
if start_view anywhere "$work/run" --listen 0.0.0.0:0; then
    grep -q "warning: serving on 0.0.0.0, reachable from other machines" "$work/anywhere.err" &&
        echo "ok   0.0.0.0: $(cat "$work/anywhere.err")" || fail "no warning for 0.0.0.0"
fi
grep -q warning "$work/finished.err" && fail "warning for loopback"

# 6. the page in a real browser (skipped only without chromium or web/node_modules)
chromium=$(command -v chromium || command -v chromium-browser || true)
if [ -z "$chromium" ] || [ ! -d "$src/web/node_modules/puppeteer-core" ]; then
    echo "SKIP browser test: needs chromium and web/node_modules (make deps installs both)"
else
    mkdir -p "$out"
    node "$src/tests/browser/simulate_run.mjs" "$work/run" "$work/growing" 2 0
    start_view growing_view "$work/growing" --listen 127.0.0.1:0 && growing=$base
    start_view finished_view "$work/run" --listen 127.0.0.1:0 && finished=$base
    timeout 300 node "$src/tests/browser/view_browser.mjs" "$src/web" "$chromium" "$out" \
        "$finished" "$work/run" "$growing" "$work/growing" || fail "browser test"
fi

[ "$failures" -eq 0 ] || { echo "$failures failure(s)"; exit 1; }
echo "all view checks passed"
