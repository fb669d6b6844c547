# Sourced by the CLI tests that start servers (rths view, rths controller) or other background
# processes (a campaign, a host run): every process registered in `servers` (`servers+=($!)`)
# is stopped when the script exits, whatever its outcome (a failed check, `exit`, an error,
# TERM/INT/HUP from ctest or a user): SIGTERM, then SIGKILL to what still runs after 10 s, and
# waited for. The folders listed in `scratch_dirs` are removed after (common.sh's $work is one).
# A script killed by SIGKILL runs no trap: start each server under `timeout -k 5 $life` so that
# it outlives the script by at most $life seconds. Kept out of tests/cli/*.sh, which CMake
# registers as tests one by one.
servers=()
scratch_dirs=()
[ -n "${work:-}" ] && scratch_dirs+=("$work")
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

stop_all_and_clean() {
    local rc=$?
    stop_all
    [ ${#scratch_dirs[@]} -eq 0 ] || rm -rf "${scratch_dirs[@]}"
    return $rc
}
trap stop_all_and_clean EXIT
trap 'exit 143' TERM
trap 'exit 130' INT
trap 'exit 129' HUP

# none_left PATTERN: the script's last check, that no process whose command line holds PATTERN
# (the script's scratch folder, a port) is left.
none_left() {
    stop_all
    local left
    left=$(pgrep -af -- "$1" | grep -v "^$$ " || true)
    [ -z "$left" ]
}

# start_controller NAME ARGS...: `rths controller ARGS` ($bin) in the background, its stdout and
# stderr in $work/NAME.out and $work/NAME.err, registered in servers; waits (20 s at most) for its
# "listening on 127.0.0.1:PORT" line. Sets port (empty when the controller ended or never
# listened) and last_pid. Not under `timeout`: a test kills the controller itself (SIGKILL, a lost
# site), and a timeout in between would survive it.
start_controller() {
    local name=$1
    shift
    "$bin" controller "$@" >"$work/$name.out" 2>"$work/$name.err" &
    last_pid=$!
    servers+=("$last_pid")
    port=
    for _ in $(seq 1 400); do
        port=$(sed -n 's/^listening on 127\.0\.0\.1:\([0-9][0-9]*\)$/\1/p' "$work/$name.out")
        [ -n "$port" ] && break
        kill -0 "$last_pid" 2>/dev/null || break
        sleep 0.05
    done
}

# start_site N NAME ARGS...: the controller of site N of $cfg (a multi-site file, docs/method.md
# "Multi-site tests") on a free loopback port, not real-time, host watchdog 10 s; sets port and
# last_pid; a site that does not start fails the script (exit 1).
start_site() {
    local n=$1 name=$2
    shift 2
    start_controller "$name" "$cfg" --site "$n" --listen 127.0.0.1:0 --set server.realtime=false \
        --set server.watchdog_s=10 "$@"
    [ -n "$port" ] || { fail "site $n did not start: $(cat "$work/$name.err")"; exit 1; }
}
