#!/usr/bin/env bash
# A multi-site test on loopback (examples/two_site_frame.yaml; docs/method.md, "Multi-site
# tests"): storey 1's columns at site A, the roof's tuned-mass damper at site B, each site its
# own `rths controller --site N` process, the host joining them with --rig once per site and
# solving the numerical floor between them per harmonic.
# 1. noise off, injected one-way link delay 0, 50 and 500 ms (RTHS_TEST_LINK_DELAY_S): every
#    point converges and both interface DoFs (floor 1, roof) are within 0.5 % of the assembly's
#    analytic FRF (numpy's complex solve of the 4-DoF chain; measured below 0.01 %);
#    summary.json and run.log report each site's rig time, and the latency costs rig time;
# 2. default noise, delay 0: every point equals the single-process run (the same file on the
#    virtual rig, no URIs) within 3 standard errors of their difference, both DoFs;
# 3. site B's controller killed mid-run: the host stops (exit 1) naming site 2's lost link,
#    says every other site was disarmed, and keeps every accepted point (frf.csv = journal).
# Late samples are tolerated (controller.max_overrun_share=1): the simulated plant's samples do
# not depend on when they run, and a test machine is not real-time.
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"
cfg="$src/examples/two_site_frame.yaml"
# every controller and host started here is stopped whatever the outcome; start_site starts one
source "$src/tests/cli/lib/servers.sh"

host=(--set controller.max_overrun_share=1 --quiet)
short=(--set continuation.start_hz=18.0 --set continuation.end_hz=18.2)

check_truth() { # out_dir label
    /usr/bin/python3 - "$1" "$2" <<'PY'
import csv, json, sys
import numpy as np
d, label = sys.argv[1], sys.argv[2]
def chain(v):
    n = len(v); a = np.zeros((n, n))
    for i in range(n):
        a[i, i] += v[i]
        if i > 0:
            a[i, i - 1] -= v[i]; a[i - 1, i] -= v[i]; a[i - 1, i - 1] += v[i]
    return a
M = np.diag([5.37, 5.37, 5.37, 0.537])
C = chain([4.4062, 3.7979, 3.7421, 3.4809])
K = chain([53048, 45724, 45052, 881.38])
f = np.array([0, 1.0, 0, 0])
rows = list(csv.DictReader(open(f"{d}/frf.csv")))
worst = 0.0
for r in rows:
    w = 2 * np.pi * float(r["frequency_hz"])
    x = np.abs(np.linalg.solve(K - w * w * M + 1j * w * C, f))
    for col, dof in (("dof1_amplitude_m", 0), ("dof2_amplitude_m", 2)):
        worst = max(worst, abs(float(r[col]) / x[dof] - 1))
s = json.load(open(f"{d}/summary.json"))
sites = s.get("sites", [])
times = [site["rig_time_s"] for site in sites]
log = open(f"{d}/run.log").read()
print(f"{label}: {len(rows)} points, worst error {100 * worst:.4f} %, rig time {s['rig_time_s']:.1f} s, "
      f"per site {', '.join(f'{t:.1f} s' for t in times)}")
ok = len(rows) >= 2 and all(r["converged"] == "1" for r in rows) and worst < 0.005
ok = ok and len(sites) == 2 and all(t > 0 for t in times)
ok = ok and [site["interface_dofs"] for site in sites] == [[1], [3]]
ok = ok and all(f"site {k} tcp://127.0.0.1:" in log and "rig time" in log for k in (1, 2))
ok = ok and log.count(" accepted: ") == len(rows)
sys.exit(0 if ok else 1)
PY
}

# 1. noise off at three link delays (one pair of controllers serves the three hosts in turn)
start_site 1 a0 --set rig.noise=false
rig_a=$port
start_site 2 b0 --set rig.noise=false
rig_b=$port
rigs=(--rig "tcp://127.0.0.1:$rig_a" --rig "tcp://127.0.0.1:$rig_b")
for delay in 0 0.05 0.5; do
    extra=()
    [ "$delay" = 0 ] || extra=("${short[@]}") # a slow link: two points
    RTHS_TEST_LINK_DELAY_S=$delay "$bin" frf "$cfg" "${rigs[@]}" --out "$work/off_$delay" \
        --set rig.noise=false "${host[@]}" "${extra[@]}" 2>"$work/off_$delay.err" ||
        fail "delay $delay s: rths frf exited $? ($(cat "$work/off_$delay.err"))"
    check_truth "$work/off_$delay" "noise off, delay $delay s" || fail "delay $delay s: accuracy or sites"
done
# the latency costs rig time: the same two points take longer per evaluation at 500 ms
/usr/bin/python3 - "$work" <<'PY' || fail "rig time per evaluation does not grow with the delay"
import csv, sys
def per_eval(d, lo=17.99, hi=18.21):
    rows = [r for r in csv.DictReader(open(f"{d}/frf.csv")) if lo <= float(r["frequency_hz"]) <= hi]
    return sum(float(r["rig_time_s"]) for r in rows) / sum(int(r["evaluations"]) for r in rows)
a, b = per_eval(f"{sys.argv[1]}/off_0"), per_eval(f"{sys.argv[1]}/off_0.5")
print(f"rig time per evaluation: {a:.2f} s at 0 ms, {b:.2f} s at 500 ms one-way")
sys.exit(0 if b > a else 1)
PY
[ "$failures" -eq 0 ] && echo "ok   two sites, delays 0, 50, 500 ms: within 0.5 % of the analytic FRF"

# 2. default noise: the two-site run against the single-process run of the same file
stop_all
start_site 1 a1
rig_a=$port
start_site 2 b1
rig_b=$port
"$bin" frf "$cfg" --rig "tcp://127.0.0.1:$rig_a" --rig "tcp://127.0.0.1:$rig_b" --out "$work/on2" \
    "${host[@]}" 2>"$work/on2.err" || fail "noise, two sites: rths frf exited $? ($(cat "$work/on2.err"))"
"$bin" frf "$cfg" --out "$work/on1" "${host[@]}" 2>"$work/on1.err" ||
    fail "noise, single process: rths frf exited $? ($(cat "$work/on1.err"))"
/usr/bin/python3 - "$work" <<'PY' || fail "noise: the two-site run differs from the single-process run"
import csv, math, sys
w = sys.argv[1]
two = list(csv.DictReader(open(f"{w}/on2/frf.csv")))
one = {round(float(r["frequency_hz"]), 6): r for r in csv.DictReader(open(f"{w}/on1/frf.csv"))}
worst, n = 0.0, 0
for r in two:
    s = one.get(round(float(r["frequency_hz"]), 6))
    if s is None:
        continue
    for d in (1, 2):
        a, b = float(r[f"dof{d}_amplitude_m"]), float(s[f"dof{d}_amplitude_m"])
        se = math.hypot(float(r[f"dof{d}_amplitude_se_m"]), float(s[f"dof{d}_amplitude_se_m"]))
        worst = max(worst, abs(a - b) / se)
        n += 1
print(f"noise: {n} DoF-points compared, worst |two-site - single| = {worst:.2f} SE")
sys.exit(0 if n >= 6 and worst <= 3 else 1)
PY
[ "$failures" -eq 0 ] && echo "ok   with noise the two sites equal the single-process run within 3 SE"

# 3. site B's controller killed mid-run
"$bin" frf "$cfg" --rig "tcp://127.0.0.1:$rig_a" --rig "tcp://127.0.0.1:$rig_b" --out "$work/lost" \
    "${host[@]}" --set continuation.end_hz=19 >"$work/lost.out" 2>"$work/lost.err" &
hpid=$!
servers+=($hpid)
for _ in $(seq 1 1200); do
    [ "$(wc -l 2>/dev/null <"$work/lost/journal.jsonl" || echo 0)" -ge 2 ] && break
    kill -0 "$hpid" 2>/dev/null || break
    sleep 0.05
done
kill -9 "$last_pid"
wait "$hpid"
rc=$?
forget "$hpid"
[ "$rc" -eq 1 ] || fail "lost site: exit $rc, expected 1 ($(cat "$work/lost.err"))"
grep -q "site 2 (tcp://127.0.0.1:$rig_b)" "$work/lost.err" || fail "lost site not named: $(cat "$work/lost.err")"
grep -q "every other site was disarmed" "$work/lost.err" || fail "the other site's disarm is not said: $(cat "$work/lost.err")"
/usr/bin/python3 - "$work/lost" <<'PY' || fail "lost site: accepted points not all saved"
import csv, sys
d = sys.argv[1]
rows = list(csv.DictReader(open(f"{d}/frf.csv")))
journal = sum(1 for l in open(f"{d}/journal.jsonl")) - 1
print(f"lost site: {len(rows)} points saved, journal {journal} records")
sys.exit(0 if len(rows) >= 1 and len(rows) == journal else 1)
PY
[ "$failures" -eq 0 ] && echo "ok   a lost site ends the run, every site disarmed, every point saved"
exit $((failures > 0))
