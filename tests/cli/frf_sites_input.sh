#!/usr/bin/env bash
# Multi-site tests refuse bad input before anything is written or connected (exit 2, the message
# naming the problem; docs/method.md, "Multi-site tests"):
# - the real-time numerical form when the numerical side couples the sites (floor 2 of
#   examples/two_site_frame.yaml joins site A's floor 1 to site B's roof);
# - a count of --rig that differs from rig.sites', one --rig with rig.sites, URIs for some sites;
# - an interface DoF in two sites or in none, a physical element shared by two sites;
# - rths controller --site N beyond the list, or without rig.sites.
# And `rths controller CONFIG --site N` derives the site's split (printed on stderr).
set -u
bin=$1
src=$2
. "$src/tests/cli/lib/common.sh"
cfg="$src/examples/two_site_frame.yaml"
two=(--rig tcp://127.0.0.1:1 --rig tcp://127.0.0.1:2)

refused frf "real-time form with coupled sites" \
    "numerical DoF 2 is joined.*split.numerical_solver: frequency" \
    "$cfg" "${two[@]}" --set split.numerical_solver=realtime
refused frf "three --rig for two sites" "--rig given 3 times; rig.sites lists 2 sites" \
    "$cfg" "${two[@]}" --rig tcp://127.0.0.1:3
refused frf "one --rig with rig.sites" "rig.sites lists 2 sites: give --rig once per site" \
    "$cfg" --rig tcp://127.0.0.1:1
refused frf "a URI for one site only" "rig.sites.1.*has no uri" \
    "$cfg" --set rig.sites.0.uri=tcp://127.0.0.1:1
refused frf "an interface DoF in two sites" "DoF 1 is driven by site 1 already" \
    "$cfg" "${two[@]}" "--set" "rig.sites.1.interface_dofs=[1, 3]"
refused frf "an interface DoF in no site" "interface DoF 2 \(split.interface\) is driven by no site" \
    "$cfg" "${two[@]}" "--set" "split.interface=[1, 2, 3]" "--set" "split.numerical=[]"
refused frf "a site without DoFs" "rig.sites.1.interface_dofs': lists 0 DoFs" \
    "$cfg" "${two[@]}" "--set" "rig.sites.1.interface_dofs=[]"
# the damper (DoF 4) hung from floor 1 instead of the roof: site B's physical part would join site
# A's: a shared physical element
refused frf "a physical element shared by two sites" "share an element of the physical side" \
    "$cfg" "${two[@]}" "--set" "split.interface=[1, 3]" "--set" "split.physical=[2, 4]" \
    "--set" "split.numerical=[]"
refused frf "output.dofs with sites" "output.dofs.*not supported with rig.sites" \
    "$cfg" "${two[@]}" "--set" "output.dofs=[2]"

# rths controller --site: beyond the list, and without rig.sites (exit 2, nothing started)
"$bin" controller "$cfg" --site 3 --listen 127.0.0.1:0 --duration 1 >/dev/null 2>"$work/c3.err"
rc=$?
[ "$rc" -eq 2 ] && grep -q -- "--site 3: the configuration's rig.sites lists 2 site(s)" "$work/c3.err" ||
    fail "--site 3: exit $rc, $(cat "$work/c3.err")"
"$bin" controller "$src/examples/four_storey.yaml" --site 1 --listen 127.0.0.1:0 --duration 1 \
    >/dev/null 2>"$work/c0.err"
rc=$?
[ "$rc" -eq 2 ] && grep -q "lists no rig.sites" "$work/c0.err" || fail "--site without rig.sites: exit $rc, $(cat "$work/c0.err")"
# each site's split: its interface and physical DoFs, every other DoF numerical
for n in 1 2; do
    "$bin" controller "$cfg" --site "$n" --listen 127.0.0.1:0 --duration 0.2 \
        --set server.realtime=false >/dev/null 2>"$work/s$n.err" || fail "--site $n: exit $?"
done
grep -q "site 1: split.interface=\[1\] split.physical=\[\] split.numerical=\[2, 3, 4\]" "$work/s1.err" ||
    fail "site 1's split: $(head -n 1 "$work/s1.err")"
grep -q "site 2: split.interface=\[3\] split.physical=\[4\] split.numerical=\[1, 2\]" "$work/s2.err" ||
    fail "site 2's split: $(head -n 1 "$work/s2.err")"
[ "$failures" -eq 0 ] && echo "ok   rths controller --site derives each site's split"
exit $((failures > 0))
