#!/usr/bin/env bash
# rths view: the JSON API against a real run's files (finished, and journal-only as while the run
# is in progress), refusals (bad command lines, missing/non-run folders, path traversal, a port in
# use), a free port picked, loopback by default, a vanished folder survived; then the page in
# headless Chromium (tests/browser/view_browser.mjs: no console error, drawn points = frf.csv, a
# screenshot that is not blank, a growing run followed; a two-interface run's every DoF and a
# bilinear run's unstable points drawn as frf.csv says: view_runs_browser.mjs), a real run paced by rig.pace watched from
# start to end (paced_browser.mjs), and the controller process's page on a driven controller
# (controller_browser.mjs). Screenshots stay in view-test-output/.
# Every process started here is stopped whatever the outcome (stop_all, on EXIT and on TERM, INT,
# HUP), each server also runs under `timeout` so that not even a SIGKILLed script leaves one for
# long, and the script's last check is that none is left.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
out="$PWD/view-test-output"
servers=() # every background process started here: views, runs, the controller and its host
trap 'stop_all; rm -rf "$work"' EXIT
trap 'exit 143' TERM
trap 'exit 130' INT
trap 'exit 129' HUP
# A server outlives a killed script by at most this long (timeout's own limit).
life=900

# alive PID: running, not a zombie waiting to be reaped
alive() {
    local stat
    stat=$(cat "/proc/$1/stat" 2>/dev/null) || return 1
    stat=${stat##*) }
    [ "${stat:0:1}" != Z ]
}

# forget PID: a process waited for here leaves servers (its pid may be reused)
forget() {
    local keep=() p
    for p in "${servers[@]}"; do [ "$p" = "$1" ] || keep+=("$p"); done
    servers=("${keep[@]}")
}

# stop_all: SIGTERM to every process in servers, then waits for them; SIGKILL to what still runs
# after 10 s.
stop_all() {
    [ ${#servers[@]} -gt 0 ] || return 0
    local p left
    kill -TERM "${servers[@]}" 2>/dev/null
    for _ in $(seq 100); do
        left=0
        for p in "${servers[@]}"; do alive "$p" && left=1; done
        [ $left = 0 ] && break
        sleep 0.1
    done
    kill -KILL "${servers[@]}" 2>/dev/null
    wait "${servers[@]}" 2>/dev/null
    servers=()
}

command -v node >/dev/null || { echo "FAIL node is missing (make deps installs nodejs)"; exit 1; }

# start_view NAME RUN_DIR [ARGS...]: starts `rths view` in the background and waits for the line
# giving its address; sets $port and $base. Returns 1 if it never served.
start_view() {
    local name=$1
    shift
    timeout -k 5 $life "$bin" view "$@" >"$work/$name.out" 2>"$work/$name.err" &
    servers+=($!)
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
    # live pages hold a server thread each: the 9th event stream is refused (503) and the API
    # still answers (16 streams used to take every thread); the 9th asks once all 8 have begun.
    # A stream api_check.mjs left ends at the server's next keep-alive (within 2 s): a stream
    # refused meanwhile is asked for again.
    streams=()
    stream() { curl -s -N --max-time 25 "${base}api/events" >"$work/ev$1" & streams[$1]=$!; }
    for i in 1 2 3 4 5 6 7 8; do stream $i; done
    for _ in $(seq 150); do
        begun=0
        for i in 1 2 3 4 5 6 7 8; do
            if grep -q "^retry:" "$work/ev$i"; then begun=$((begun + 1))
            elif grep -q "too many live pages" "$work/ev$i"; then wait "${streams[$i]}"; stream $i; fi
        done
        [ $begun = 8 ] && break
        sleep 0.1
    done
    code=$(curl -s -D "$work/ev9.head" -o "$work/ev9" -w '%{http_code}' --max-time 5 "${base}api/events")
    [ "$code" = 503 ] && grep -q "too many live pages" "$work/ev9" &&
        grep -q "503 Service Unavailable" "$work/ev9.head" &&
        echo "ok   9th event stream: 503 Service Unavailable, $(cat "$work/ev9")" ||
        fail "9th event stream: HTTP $code ($begun streams begun), $(head -n 1 "$work/ev9.head")"
    code=$(curl -s -o /dev/null -w '%{http_code}' --max-time 5 "${base}api/status")
    [ "$code" = 200 ] && echo "ok   the API answers with 8 streams open" ||
        fail "API with 8 streams open: HTTP $code"
    kill "${streams[@]}" 2>/dev/null
    wait "${streams[@]}" 2>/dev/null
fi

# 3. in progress: no frf.csv or summary.json yet, the points come from the journal and must
# equal what the run later writes to frf.csv
cp -r "$work/run" "$work/inprogress"
rm "$work/inprogress/frf.csv" "$work/inprogress/summary.json"
if start_view inprogress "$work/inprogress" --listen 127.0.0.1:0; then
    node "$src/tests/browser/api_check.mjs" "$base" "$work/inprogress" "$work/run/frf.csv" journal.jsonl $uplot ||
        fail "API of a run in progress"
    # a symlink out of the folder is refused without a byte of its target; an encoded NUL is
    # refused; HEAD of the event stream ends (the command's own server: test_view has the rest)
    mv "$work/inprogress/live.json" "$work/live.json.saved"
    ln -s /etc/passwd "$work/inprogress/live.json"
    code=$(curl -s -o "$work/linked" -w '%{http_code}' --max-time 5 "${base}api/live")
    [ "$code" = 403 ] && ! grep -q "root:" "$work/linked" && echo "ok   symlinked live.json: 403, $(cat "$work/linked")" ||
        fail "symlinked live.json: HTTP $code"
    rm "$work/inprogress/live.json"
    mv "$work/live.json.saved" "$work/inprogress/live.json"
    code=$(curl -s -o /dev/null -w '%{http_code}' --max-time 5 "${base}run/truth.csv%00.png")
    [ "$code" = 400 ] && echo "ok   /run/truth.csv%00.png: 400" || fail "/run/truth.csv%00.png: HTTP $code"
    code=$(curl -s -I -o "$work/head" -w '%{http_code}' --max-time 5 "${base}api/events")
    [ "$code" = 200 ] && grep -q "text/event-stream" "$work/head" && echo "ok   HEAD /api/events: 200, no stream" ||
        fail "HEAD /api/events: HTTP $code"
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

    # 6b. several interface DoFs (every DoF's points) and a nonlinear run (unstable points open)
    "$bin" frf "$src/examples/two_interface_storeys.yaml" --out "$work/two" --quiet ||
        fail "two-interface frf run"
    "$bin" frf "$src/examples/four_storey_bilinear.yaml" --out "$work/bilinear" --quiet ||
        fail "bilinear frf run"
    start_view two_view "$work/two" --listen 127.0.0.1:0 && two=$base
    start_view bilinear_view "$work/bilinear" --listen 127.0.0.1:0 && bilinear=$base
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) c[$i] = i; next } $c["stable"] == 0 { n++ }
             END { exit !(n > 0) }' "$work/bilinear/frf.csv" || fail "bilinear run has no unstable point"
    timeout 300 node "$src/tests/browser/view_runs_browser.mjs" "$src/web" "$chromium" "$out" \
        two_interface "$two" "$work/two" bilinear "$bilinear" "$work/bilinear" ||
        fail "other runs in the browser"

    # 7. a real paced run: rths frf at 4 x real time (59 s of rig time: about 15 s of wall time),
    # watched from its first points to its end
    paced=(frf "$src/examples/four_storey_linear.yaml" --quiet)
    t0=$(date +%s.%N)
    "$bin" "${paced[@]}" --out "$work/paced" --set rig.pace=4 >"$work/paced.out" 2>"$work/paced.err" &
    paced_pid=$!
    servers+=($paced_pid)
    for _ in $(seq 200); do [ -s "$work/paced/journal.jsonl" ] && break; sleep 0.05; done
    if start_view paced_view "$work/paced" --listen 127.0.0.1:0; then
        timeout 300 node "$src/tests/browser/paced_browser.mjs" "$src/web" "$chromium" "$out" \
            "$base" "$work/paced" "$paced_pid" || fail "paced run in the browser"
    fi
    wait "$paced_pid" || fail "paced frf run: $(cat "$work/paced.err")"
    forget "$paced_pid"
    wall=$(echo "$(date +%s.%N) - $t0" | bc)
    # pacing only sleeps: the same numbers as unpaced, and never faster than rig time / 4 (a lower
    # bound: sleeping cannot make a run faster, so this cannot flake on a loaded machine)
    "$bin" "${paced[@]}" --out "$work/unpaced" || fail "unpaced frf run"
    cmp -s "$work/paced/frf.csv" "$work/unpaced/frf.csv" &&
        echo "ok   paced run's frf.csv identical to the unpaced run's" || fail "pacing changed frf.csv"
    rig=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "rig_time_s") c = i; next }
        { s += $c } END { print s }' "$work/paced/frf.csv")
    if [ "$(echo "$wall >= $rig / 4" | bc)" = 1 ]; then echo "ok   paced x4: $rig s of rig time took $wall s (>= $rig / 4)"
    else fail "paced x4: $rig s of rig time in $wall s"; fi

    # 8. the controller process's page: `rths controller --view`, or before the command has the
    # option the same server and page from test_view --serve-controller; a host (rths simulate
    # over TCP) drives it while the browser watches
    ctl_cfg="$src/examples/four_storey.yaml"
    if "$bin" controller --help | grep -q -- "--view"; then
        timeout -k 5 $life "$bin" controller --config "$ctl_cfg" --listen 127.0.0.1:0 \
            --view 127.0.0.1:0 --set server.realtime=false >"$work/ctl.out" 2>"$work/ctl.err" &
    else
        timeout -k 5 $life "$PWD/test_view" --serve-controller "$ctl_cfg" >"$work/ctl.out" \
            2>"$work/ctl.err" &
    fi
    servers+=($!)
    cport= vport=
    for _ in $(seq 200); do
        cport=$(sed -n 's/^listening on 127\.0\.0\.1:\([0-9][0-9]*\)$/\1/p' "$work/ctl.out")
        vport=$(sed -n 's|^view at http://127\.0\.0\.1:\([0-9][0-9]*\)/$|\1|p' "$work/ctl.out")
        [ -n "$cport" ] && [ -n "$vport" ] && break
        sleep 0.05
    done
    if [ -z "$vport" ]; then fail "controller page: no address printed: $(cat "$work/ctl.err")"
    else
        "$bin" simulate "$ctl_cfg" --out "$work/drive" --rig "tcp://127.0.0.1:$cport" --frequency 13 \
            --target 2e-5,-1e-5 --periods 400 --quiet >"$work/drive.out" 2>"$work/drive.err" &
        drive_pid=$!
        servers+=($drive_pid)
        timeout 120 node "$src/tests/browser/controller_browser.mjs" "$src/web" "$chromium" "$out" \
            "http://127.0.0.1:$vport/" || fail "controller page in the browser"
        kill "$drive_pid" 2>/dev/null
        wait "$drive_pid" 2>/dev/null
        forget "$drive_pid"
    fi
fi

# 9. nothing this script started is left: every server stopped and waited for (a `pids=()` here
# once dropped the first view, which outlived every `make test`)
stop_all
left=$(pgrep -af -- "$work" || true)
[ -z "$left" ] && echo "ok   every process started here has ended" || fail "still running: $left"

[ "$failures" -eq 0 ] || { echo "$failures failure(s)"; exit 1; }
echo "all view checks passed"
