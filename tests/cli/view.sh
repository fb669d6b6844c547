#!/usr/bin/env bash
# rths view: the JSON API against a real run's files (finished, and journal-only as while the run
# is in progress), refusals (bad command lines, missing/non-run folders, path traversal, a port in
# use), a free port picked, loopback by default, a vanished folder survived; then the page in
# headless Chromium (tests/browser/view_browser.mjs: no console error, drawn points = frf.csv, a
# screenshot that is not blank, a growing run followed; a two-interface run's every DoF and a
# bilinear run's unstable points drawn as frf.csv says: view_runs_browser.mjs), a real run paced by rig.pace watched from
# start to end (paced_browser.mjs), and the controller process's page on a driven controller
# (controller_browser.mjs); a campaign folder (rths campaign --out) followed while it runs, its
# table as campaign.csv, each run's page and API under /runs/run_K/ and the path rules there, its
# page in the browser (campaign_browser.mjs). Screenshots stay in view-test-output/.
# Every process started here is stopped whatever the outcome (stop_all of tests/cli/lib/servers.sh,
# on EXIT and on TERM, INT, HUP), each server also runs under `timeout` so that not even a
# SIGKILLed script leaves one for long, and the script's last check is that none is left.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"
out="$PWD/view-test-output"
source "$src/tests/cli/lib/servers.sh" # servers, stop_all (on exit, whatever the outcome), life

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
    stream() {
        curl -s -N --max-time 25 "${base}api/events" >"$work/ev$1" &
        streams[$1]=$!
        servers+=($!)
    }
    for i in 1 2 3 4 5 6 7 8; do stream $i; done
    for _ in $(seq 150); do
        begun=0
        for i in 1 2 3 4 5 6 7 8; do
            if grep -q "^retry:" "$work/ev$i"; then begun=$((begun + 1))
            elif grep -q "too many live pages" "$work/ev$i"; then
                wait "${streams[$i]}"
                forget "${streams[$i]}"
                stream $i
            fi
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
    for p in "${streams[@]}"; do forget "$p"; done
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

# 5b. a campaign folder (rths campaign --out, docs/campaign.md): served while the campaign runs
# (4 runs, 2 at a time) and followed until it has ended; /api/campaign equals campaign.csv value
# for value; each run's page and API under /runs/run_K/ (api_check.mjs under that prefix); the
# path rules of /runs/ (run_ and digits, a folder of the campaign, not a link, holding a run)
cplan="$work/campaign.yaml"
printf 'config: %s\nset:\n  continuation.start_hz: 12.0\n  continuation.end_hz: 12.2\ngrid:\n  split.mass_ratio: [0.4, 0.6]\n  controller.kp_v_per_m: [100, 150]\n' \
    "$src/examples/four_storey_linear.yaml" >"$cplan"
timeout -k 5 $life "$bin" campaign "$cplan" --out "$work/campaign" --jobs 2 --quiet \
    >"$work/campaign.out" 2>&1 &
campaign_pid=$!
servers+=($campaign_pid)
for _ in $(seq 600); do [ -f "$work/campaign/plan.txt" ] && break; sleep 0.1; done
campaign_base=""
# status_of URL: "STATE FINISHED RUNS" of a campaign's /api/status
campaign_status() {
    curl -s --max-time 5 "$1api/status" | node -e 'let s = ""; process.stdin.on("data", (d) => (s += d)).on("end", () => {
        try { const j = JSON.parse(s); console.log(j.kind, j.state, j.campaign.finished, j.campaign.runs); } catch { console.log("?"); } })'
}
if start_view campaign_view "$work/campaign" --listen 127.0.0.1:0; then
    campaign_base=$base
    seen=""
    for _ in $(seq 1200); do
        st=$(campaign_status "$campaign_base")
        [ "$st" != "${seen##*; }" ] && seen="$seen; $st"
        [ "$st" = "campaign ended 4 4" ] && break
        sleep 0.25
    done
    [ "${seen##*; }" = "campaign ended 4 4" ] && echo "ok   campaign followed to its end:$seen" ||
        fail "campaign status: $seen"
fi
wait "$campaign_pid" || fail "campaign exit $?: $(cat "$work/campaign.out")"
forget "$campaign_pid"
if [ -n "$campaign_base" ]; then
    # /api/campaign against campaign.csv: the same text or number in every cell
    node - "$campaign_base" "$work/campaign/campaign.csv" <<'JS' || fail "/api/campaign differs from campaign.csv"
const [base, file] = process.argv.slice(2);
const [head, ...rows] = require("fs").readFileSync(file, "utf8").trim().split("\n");
const cols = head.split(",");
fetch(`${base}api/campaign`).then((r) => r.json()).then((j) => {
  let bad = j.columns.join() !== head || j.runs.length !== rows.length || j.grid.join() !== "split.mass_ratio,controller.kp_v_per_m";
  rows.forEach((r, i) => r.split(",").forEach((v, c) => {
    const got = j.runs[i][cols[c]], want = c === 0 ? v : v === "" ? null : Number(v);
    if (got !== want) { console.log(`row ${i} ${cols[c]}: ${got} != ${want}`); bad = true; }
  }));
  if (!j.run_folders.every((x) => x)) bad = true;
  console.log(bad ? "FAIL /api/campaign" : `ok   /api/campaign equals campaign.csv (${rows.length} runs x ${cols.length} columns)`);
  process.exit(bad ? 1 : 0);
});
JS
    # run 2's page and API under /runs/run_0002/, with the run view's own checks
    crun="$work/campaign/run_0002"
    ln -s /etc/passwd "$crun/outside_link"
    node "$src/tests/browser/api_check.mjs" "${campaign_base}runs/run_0002/" "$crun" "$crun/frf.csv" frf.csv $uplot ||
        fail "API of a campaign's run"
    code=$(curl -s -o /dev/null -w '%{http_code} %{redirect_url}' --max-time 5 "${campaign_base}runs/run_0002")
    [ "$code" = "301 ${campaign_base}runs/run_0002/" ] && echo "ok   /runs/run_0002: 301 to /runs/run_0002/" ||
        fail "/runs/run_0002: $code"
    ln -s "$crun" "$work/campaign/run_0009"
    mkdir "$work/campaign/run_0010"
    for p in runs/run_0009/api/points runs/run_0010/ runs/run_0011/ runs/logs/ runs/run_0002x/ api/points; do
        code=$(curl -s -o "$work/body" -w '%{http_code}' --max-time 5 "${campaign_base}$p")
        [ "$code" = 404 ] && ! grep -q "frequency_hz" "$work/body" && echo "ok   /$p: 404" || fail "/$p: HTTP $code"
    done
    for p in runs/../campaign.csv runs/run_0002/../../etc/passwd runs/%2e%2e/campaign.csv runs/run_0002/run/..%2f..%2fcampaign.csv; do
        code=$(curl -s --path-as-is -o "$work/body" -w '%{http_code}' --max-time 5 "${campaign_base}$p")
        [ "$code" = 403 ] && ! grep -q "root:" "$work/body" && echo "ok   /$p: 403" || fail "/$p: HTTP $code"
    done
    rm "$work/campaign/run_0009" && rmdir "$work/campaign/run_0010"
fi

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

    # 6c. the campaign's page: its table, sorting, plots, a run's page through its link, and a
    # copy whose campaign.csv is rewritten run by run followed without a reload
    if [ -n "$campaign_base" ]; then
        cp -r "$work/campaign" "$work/campaign_live"
        start_view campaign_live_view "$work/campaign_live" --listen 127.0.0.1:0 && campaign_live=$base
        timeout 300 node "$src/tests/browser/campaign_browser.mjs" "$src/web" "$chromium" "$out" \
            "$campaign_base" "$work/campaign" "$campaign_live" "$work/campaign_live" ||
            fail "campaign page in the browser"
    fi

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
