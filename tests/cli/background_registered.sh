#!/usr/bin/env bash
# Every CLI test that starts a process in the background stops it, whatever its outcome (issue
# 28: a fresh `make test` left `rths view ... --listen 127.0.0.1:0` processes running). The way
# is tests/cli/lib/servers.sh (its EXIT/TERM/INT/HUP traps stop every pid in `servers`;
# view_servers_stopped.sh shows that they do): so each tests/cli/*.sh with a command sent to the
# background (a line ending in a single `&`, or `& name=$!`) must source servers.sh and register
# the process (`servers+=`) on that line or within the 5 lines after it. Heredoc bodies (inner
# scripts, Python) are skipped. A script that ran `rths frf ... &` with no trap (frf_guards.sh
# before this test) fails it, named FILE:LINE.
set -u
bin=$1
src=$2
source "$src/tests/cli/lib/common.sh"

/usr/bin/python3 - "$src/tests/cli" <<'PY' || fail "background processes not registered (above)"
import glob, os, re, sys

background = re.compile(r"(^|[^&>|])&\s*($|#|[A-Za-z_][A-Za-z_0-9]*(\[[^]]*\])?=\$!)")
heredoc = re.compile(r"<<-?\s*'?\"?([A-Za-z_]+)'?\"?")
bad = 0
scripts = sorted(glob.glob(os.path.join(sys.argv[1], "*.sh")))
for path in scripts:
    lines = open(path).read().split("\n")
    sources = any(re.search(r"^\s*(source|\.)\s.*lib/servers\.sh", l) for l in lines)
    end = None  # the heredoc's terminator while inside one
    found = []
    for i, line in enumerate(lines):
        if end is not None:
            if line.strip() == end:
                end = None
            continue
        code = line.split(" #", 1)[0] if not line.lstrip().startswith("#") else ""
        if background.search(code):
            found.append(i)
        m = heredoc.search(code)
        if m:
            end = m.group(1)
    name = os.path.basename(path)
    before = bad
    for i in found:
        window = "\n".join(lines[i:i + 6])
        where = f"{name}:{i + 1}"
        if not sources:
            print(f"FAIL {where}: a background process, and the script does not source lib/servers.sh")
            bad += 1
        elif "servers+=" not in window:
            print(f"FAIL {where}: a background process not registered in servers within 5 lines")
            bad += 1
    if found and bad == before:
        print(f"ok   {name}: {len(found)} background process(es), each registered in servers")
print(f"{len(scripts)} scripts read")
sys.exit(1 if bad else 0)
PY
exit $((failures > 0))
