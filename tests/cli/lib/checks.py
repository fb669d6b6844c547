"""The CLI tests' tally of named checks: each prints "ok:" or "WRONG:" with what it checked, and
exit_status() is the script's exit status (0 when every check held)."""
_all_held = True


def check(cond, what):
    global _all_held
    print(("ok:    " if cond else "WRONG: ") + what)
    _all_held = _all_held and bool(cond)


def exit_status():
    return 0 if _all_held else 1
