#!/usr/bin/env bash
# Licence check (docs/architecture.md, "Sparse algebra"): the built binaries link no GPL code.
# Decided from the dynamic symbols, not from library names: for every object loaded with a binary
# (the binary and its ldd closure), each symbol it imports (nm -D --undefined-only) is resolved to
# the first library of the closure that defines it (nm -D --defined-only, ldd's load order, as
# the dynamic linker's global scope does), and the check fails when
#   - the symbol belongs to a GPL part of SuiteSparse: UMFPACK (umfpack_*), SPQR (SuiteSparseQR*,
#     spqr_*), CHOLMOD's GPL modules: Supernodal (cholmod_super_*), Modify (cholmod_updown*,
#     cholmod_rowadd*, cholmod_rowdel*), MatrixOps (cholmod_drop, _horzcat, _vertcat, _norm_*,
#     _scale, _sdmult, _ssmult, _submatrix, _symmetry), Partition (cholmod_nested_dissection,
#     _metis*, _bisect, _camd, _ccolamd, _csymamd, _collapse_septree); CHOLMOD's LGPL Core and
#     Cholesky symbols stay allowed; or
#   - it comes from a library that is GPL as a whole, recognised by the symbols it defines: GSL
#     (gsl_*), FFTW (fftw_*, fftwf_*, fftwl_*, fftwq_*), UMFPACK, SPQR, GNU readline (readline,
#     rl_*).
#
# Usage: licence.sh RTHS_BIN SOURCE_DIR   (as ctest runs it: self-test, then the build's rths,
#                                          librths.so, rths_io_virtual.so and rths_bench if built)
#        licence.sh --check BINARY...     (check those; exit 1 naming each GPL import)
set -u

GPL_SYMBOL='^(umfpack_|SuiteSparseQR|spqr_|_Z[A-Za-z0-9_]*SuiteSparseQR|cholmod_(l_)?(super_|updown|rowadd|rowdel|drop$|horzcat$|vertcat$|norm_dense$|norm_sparse$|scale$|sdmult$|ssmult$|submatrix$|symmetry$|nested_dissection$|metis|bisect$|camd$|ccolamd$|csymamd$|collapse_septree$))'
GPL_LIBRARY_SYMBOL='^(gsl_|fftw[flq]?_|umfpack_|SuiteSparseQR|spqr_|readline$|rl_)'

# symbols OBJECT: caches "D OBJECT sym" per defined and "U OBJECT sym" per undefined global or
# weak dynamic symbol (version suffixes dropped).
symbols() {
    local key="$cache/${1//\//_}"
    [ -f "$key" ] && return
    readelf -W --dyn-syms "$1" 2>/dev/null | awk -v obj="$1" '
        $1 ~ /^[0-9]+:$/ && NF >= 8 && ($5 == "GLOBAL" || $5 == "WEAK") && $4 != "SECTION" && $4 != "FILE" {
            s = $8; sub(/@.*/, "", s)
            print ($7 == "UND" ? "U" : "D"), obj, s
        }' >"$key"
}

# check_binary BINARY: prints one line per GPL import; returns 1 if there is one.
check_binary() {
    local bin=$1 status=0
    [ -f "$bin" ] || {
        echo "licence.sh: $bin: no such file"
        return 2
    }
    local libs
    libs=$(ldd "$bin" 2>/dev/null | awk '$2 == "=>" && $3 ~ /^\// { print $3 } $1 ~ /^\// { print $1 }' | awk '!seen[$0]++')
    # one table: "D lib sym" for definitions (in ldd order), "U object sym" for imports; each
    # object's dynamic symbol table is read once per run (the binaries share most of their
    # closure) with readelf (nm -D reads the same table, three times slower)
    {
        local lib
        for lib in $libs "$bin"; do
            symbols "$lib"
        done
        for lib in "$bin" $libs; do # the executable first: the global scope's order
            grep '^D' "$cache/${lib//\//_}"
        done
        for lib in "$bin" $libs; do
            grep '^U' "$cache/${lib//\//_}"
        done
    } | awk -v bin="$bin" -v gs="$GPL_SYMBOL" -v gl="$GPL_LIBRARY_SYMBOL" '
        $1 == "D" {
            if (!($3 in provider)) provider[$3] = $2
            if ($3 ~ gl && !($2 in gpl_lib)) gpl_lib[$2] = $3
            next
        }
        {
            obj = $2; sym = $3
            if (!(sym in provider)) next      # unresolved weak symbols, or the vDSO/loader
            lib = provider[sym]
            if (lib == obj) next
            if (sym ~ gs) {
                printf "%s: %s imports %s from %s: a GPL module of SuiteSparse\n", bin, obj, sym, lib
                bad = 1
            } else if (lib in gpl_lib) {
                printf "%s: %s imports %s from %s, a GPL library (it defines %s)\n", bin, obj, sym, lib, gpl_lib[lib]
                bad = 1
            }
        }
        END { exit bad }' || status=1
    return $status
}

if [ "${1:-}" = "--check" ]; then
    shift
    cache=$(mktemp -d)
    trap 'rm -rf "$cache"' EXIT
    status=0
    for b in "$@"; do
        check_binary "$b" || status=1
    done
    exit $status
fi

bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
build=$(dirname "$bin")
self="$src/tests/cli/licence.sh"

# Self-test 1: a library that exports CHOLMOD's Supernodal symbol next to a Core one; a program
# using only the Core symbol passes, one using cholmod_super_numeric fails naming it.
cat >"$work/fake_cholmod.c" <<'C'
int cholmod_start(void *c) { (void)c; return 1; }
int cholmod_super_numeric(void *a, void *f, void *l, void *c) { (void)a; (void)f; (void)l; (void)c; return 1; }
C
cat >"$work/uses_core.c" <<'C'
int cholmod_start(void *c);
int main(void) { return !cholmod_start(0); }
C
cat >"$work/uses_super.c" <<'C'
int cholmod_start(void *c);
int cholmod_super_numeric(void *a, void *f, void *l, void *c);
int main(void) { return !cholmod_start(0) + !cholmod_super_numeric(0, 0, 0, 0); }
C
cc -shared -fPIC -o "$work/libfakecholmod.so" "$work/fake_cholmod.c" &&
    cc -o "$work/uses_core" "$work/uses_core.c" -L"$work" -lfakecholmod -Wl,-rpath,"$work" &&
    cc -o "$work/uses_super" "$work/uses_super.c" -L"$work" -lfakecholmod -Wl,-rpath,"$work" ||
    fail "self-test: cannot build the probes"
if bash "$self" --check "$work/uses_core" >"$work/core.out" 2>&1; then
    echo "ok   a program using CHOLMOD's Core only passes"
else
    fail "a program using CHOLMOD's Core only is refused: $(cat "$work/core.out")"
fi
if bash "$self" --check "$work/uses_super" >"$work/super.out" 2>&1; then
    fail "a program importing cholmod_super_numeric passes"
elif grep -q "imports cholmod_super_numeric from $work/libfakecholmod.so: a GPL module" "$work/super.out"; then
    echo "ok   $(head -n 1 "$work/super.out")"
else
    fail "cholmod_super_numeric: message: $(cat "$work/super.out")"
fi

# Self-test 2: a real GPL library, GSL (libgsl-dev, installed for this test only), found from the
# gsl_* symbols it defines (the check never looks at a library's name).
if [ -e /usr/lib/x86_64-linux-gnu/libgsl.so ] || ls /usr/lib/*/libgsl.so >/dev/null 2>&1; then
    cat >"$work/uses_gsl.c" <<'C'
double gsl_sf_bessel_J0(double x);
int main(void) { return gsl_sf_bessel_J0(0.0) != 1.0; }
C
    if cc -o "$work/uses_gsl" "$work/uses_gsl.c" -lgsl -lgslcblas -lm 2>"$work/gsl_cc.out"; then
        "$work/uses_gsl" || fail "the GSL probe does not run"
        if bash "$self" --check "$work/uses_gsl" >"$work/gsl.out" 2>&1; then
            fail "a program linked against GSL passes"
        elif grep -Eq "imports gsl_sf_bessel_J0 from /[^ ]+, a GPL library \(it defines gsl_" "$work/gsl.out"; then
            echo "ok   $(head -n 1 "$work/gsl.out")"
        else
            fail "GSL: message: $(cat "$work/gsl.out")"
        fi
    else
        fail "cannot link the GSL probe: $(cat "$work/gsl_cc.out")"
    fi
else
    echo "skip GSL probe: libgsl-dev not installed (the fake CHOLMOD probe still ran)"
fi

# The build itself.
targets=("$bin")
for t in "$build/librths.so" "$build/rths_io_virtual.so" "$build/rths_bench"; do
    [ -e "$t" ] && targets+=("$t")
done
if bash "$self" --check "${targets[@]}" >"$work/build.out" 2>&1; then
    echo "ok   no GPL symbol imported by: ${targets[*]}"
else
    fail "the build imports GPL code: $(cat "$work/build.out")"
fi
exit $((failures > 0))
