#!/usr/bin/env bash
# Hostile input to every command (issue 18): nesting 60 000 deep (file, --set, under an unknown key),
# a folder, UTF-16 and byte-order-mark files as CONFIG, options given twice, paths beyond the
# system's limits, and typos in the rig and controller sections that `rths frf` used to ignore.
# Each is refused with exit 2, a message naming the problem, and nothing written.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
cfg="$src/examples/four_storey.yaml"

# nesting: deeper than the reader's limit (64 levels), in the file, under a key nobody reads, and
# through --set; located at the bracket that opens level 65 (column 3 + 64 = 67)
python3 - "$work" <<'PY'
import sys
d, n = sys.argv[1], 60000
open(d + "/deep_list.yaml", "w").write("x: " + "[" * n + "]" * n + "\n")
open(d + "/deep_map.yaml", "w").write("unknown_section: " + "{a: " * n + "1" + "}" * n + "\n")
open(d + "/deep_set.txt", "w").write("split.x=" + "[" * n + "]" * n)
PY
for c in model fidelity chart; do
    refused "$c" "$c: deep list" "deep_list.yaml:1:67: nested deeper than 64 levels" "$work/deep_list.yaml"
    refused "$c" "$c: deep map under an unknown key" "deep_map.yaml:1:.*: nested deeper than 64 levels" "$work/deep_map.yaml"
done
refused model "deep --set" "--set split.x=\[\[\[.*nested deeper than 64 levels" "$cfg" --set "$(cat "$work/deep_set.txt")"
refused simulate "deep --set (simulate)" "nested deeper than 64 levels" "$cfg" --frequency 13 --target 1e-4,0 --periods 1 --set "$(cat "$work/deep_set.txt")"

# what is not a UTF-8 YAML file is named for what it is (these all said "structure missing")
printf '\xff\xfe' >"$work/bom.yaml"
python3 -c "import sys; open(sys.argv[1], 'wb').write(open(sys.argv[2], encoding='utf-8').read().encode('utf-16'))" \
    "$work/utf16.yaml" "$cfg"
python3 -c "import sys; open(sys.argv[1], 'wb').write(open(sys.argv[2], encoding='utf-8').read().encode('utf-16-le'))" \
    "$work/utf16_nobom.yaml" "$cfg"
mkdir -p "$work/a_folder"
# three bytes on which libfyaml 0.7 loops forever ('%' then a byte that is not UTF-8)
printf '%%"\xa6' >"$work/directive_hang.yaml"
timeout 60 "$bin" model "$work/directive_hang.yaml" --out "$work/o_hang" >/dev/null 2>"$work/bstderr"
rc=$?
[ "$rc" -eq 2 ] && grep -q "directive_hang.yaml:1:3: byte 0xA6 does not start a UTF-8 character" "$work/bstderr" ||
    fail "'%\"\\xa6' config: exit $rc (124 = hung), $(cut -c1-200 "$work/bstderr")"
refused model "byte-order mark only" "bom.yaml: starts with a UTF-16/UTF-32 byte-order mark \(FF FE\)" "$work/bom.yaml"
refused model "UTF-16 file" "utf16.yaml: starts with a UTF-16/UTF-32 byte-order mark" "$work/utf16.yaml"
refused simulate "UTF-16 without a mark" "utf16_nobom.yaml:1:2: a NUL byte" "$work/utf16_nobom.yaml" --frequency 13 --target 1e-4,0 --periods 1
refused model "folder as CONFIG" "a_folder: is a folder" "$work/a_folder"

# options given twice: the first was silently dropped; now refused
refused model "--out twice" "option --out given twice" "$cfg" --out "$work/first_out"
[ -e "$work/first_out" ] && fail "--out twice: the first folder was created"
refused simulate "--seed twice" "option --seed given twice \('1' and '2'\)" "$cfg" --frequency 13 --target 1e-4,0 --periods 1 --seed 1 --seed 2
refused simulate "--frequency twice" "option --frequency given twice" "$cfg" --frequency 13 --frequency 14 --target 1e-4,0 --periods 1

# ranges worded alike, one-sided bounds without an infinity
refused simulate "frequency beyond 1e5" "option --frequency: must be in \(0, 100000\] \(got 1e6\)" "$cfg" --frequency 1e6 --target 1e-4,0 --periods 1
refused chart "chart: integer range" "stability.tau_points': must be in \[2, 5000\] \(got 1\)" "$cfg" --set stability.tau_points=1

# paths beyond the system's limits: the reason survives in the message
long_name=$(printf 'n%.0s' $(seq 1 300))
"$bin" model "$cfg" --out "$work/$long_name" >/dev/null 2>"$work/bstderr"
rc=$?
[ "$rc" -eq 2 ] && grep -q "is 300 bytes long; the system allows 255" "$work/bstderr" ||
    fail "long --out name: exit $rc, $(cut -c1-200 "$work/bstderr")"
long_path=$(printf "$work/%.0s" $(seq 1 300))
"$bin" model "$long_path/x.yaml" --out "$work/o_long" >/dev/null 2>"$work/bstderr"
rc=$?
[ "$rc" -eq 2 ] && grep -q "CONFIG: the path is .* bytes long; the system allows 4095" "$work/bstderr" ||
    fail "long CONFIG path: exit $rc, $(cut -c1-200 "$work/bstderr")"

# every command checks every section it reads: frf with the in-process rig reads rig and
# controller (it ran with noise on when told rig.nosie=false)
refused frf "frf: misspelt rig key" "unknown key 'rig.nosie' \(did you mean 'rig.noise'\?\)" "$cfg" --set rig.nosie=false
refused frf "frf: misspelt controller key" "unknown key 'controller.kp_v_per_mm'" "$cfg" --set controller.kp_v_per_mm=3
refused frf "frf: misspelt nested rig key" "unknown key 'rig.shaker.gian_n_per_v'" "$cfg" --set rig.shaker.gian_n_per_v=3
refused simulate "simulate: misspelt rig key" "unknown key 'rig.nosie'" "$cfg" --frequency 13 --target 1e-4,0 --periods 1 --set rig.nosie=false
refused fidelity "fidelity: misspelt controller key" "unknown key 'controller.sample_rate'" "$cfg" --set controller.sample_rate=1e4
# a command without a rig still accepts those sections whole (one file serves every command)
"$bin" model "$cfg" --set rig.anything=1 --out "$work/model_ok" --quiet || fail "model refused a rig key it does not read"

# one range of matched harmonics everywhere (config and option), every one of them in frf.csv
refused frf "iteration.harmonics 4" "key 'iteration.harmonics': must be in \[1, 3\] \(got 4\)" "$cfg" --set iteration.harmonics=4
refused frf "--harmonics 4" "option --harmonics: must be in \[1, 3\]" "$cfg" --harmonics 4
# --pace: a positive factor, the in-process rig only
refused frf "--pace 0" "option --pace" "$cfg" --pace 0
refused frf "--pace with --rig" "option --pace paces the in-process virtual rig" "$cfg" --pace 2 --rig tcp://127.0.0.1:9

echo "$failures failures"
[ "$failures" -eq 0 ]
