#!/usr/bin/env bash
# tools/gen_frame3d.py on small sizes, checked with numpy (dense): with the base fixed K is
# symmetric positive definite (Cholesky succeeds, the smallest generalised eigenvalue is > 0); with
# the base free, a rigid translation along x, y and z, and a rigid rotation about each axis, cost
# no strain energy (K r = 0 to rounding) and a translation carries the sum of the element masses
# (r^T M r = sum rho A L, both mass forms); the node
# numbering differs with the seed and the matrices are the same up to it; a cantilever column of 40
# elements has the Euler-Bernoulli first bending frequencies (1.8751^2 / (2 pi)) sqrt(E I / (rho A
# L^4)) about both axes to 1 % (the FE error at 40 cubic elements is ~1e-7; the 1 % bound is the
# closed form's own, it knows nothing of the discretisation); bad sizes exit non-zero.
set -u
bin=$1
src=$2
. "$(dirname "$0")/lib/common.sh"
gen="$src/tools/gen_frame3d.py"
run() { /usr/bin/python3 "$gen" "$@" >>"$work/gen.log" 2>&1 || { fail "gen_frame3d.py $*"; cat "$work/gen.log"; }; }
run --nx 3 --ny 2 --nz 2 --elements-per-member 2 --seed 3 "$work/fixed"
run --nx 3 --ny 2 --nz 2 --elements-per-member 2 --seed 4 "$work/fixed4"
run --nx 3 --ny 2 --nz 2 --elements-per-member 2 --free-base "$work/free_c"
run --nx 3 --ny 2 --nz 2 --elements-per-member 2 --free-base --mass lumped "$work/free_l"
run --nx 1 --ny 1 --nz 1 --elements-per-member 40 --storey-m 4.0 "$work/cantilever"
run --nx 2 --ny 2 --nz 2 --mass lumped "$work/lumped"

/usr/bin/python3 - "$work" <<'PY' || fail "generated matrices fail their checks"
import sys
import numpy as np

work = sys.argv[1]
bad = 0

def check(ok, what):
    global bad
    print(("ok   " if ok else "FAIL ") + what)
    bad += not ok

def read_mtx(path):
    with open(path) as f:
        assert f.readline().startswith("%%MatrixMarket matrix coordinate real symmetric")
        line = f.readline()
        while line.startswith("%"):
            line = f.readline()
        n, _, count = map(int, line.split())
        data = np.loadtxt(f, ndmin=2)
    assert len(data) == count
    a = np.zeros((n, n))
    i, j = data[:, 0].astype(int) - 1, data[:, 1].astype(int) - 1
    assert np.all(i >= j), "lower triangle only"
    np.add.at(a, (i, j), data[:, 2])
    np.add.at(a, (j, i), np.where(i != j, data[:, 2], 0))
    return a

def info(d):
    out = {}
    with open(d + "/frame_info.txt") as f:
        for line in f:
            if line.startswith("#"):
                break
            k, v = line.split()
            out[k] = v
    nodes = np.loadtxt(d + "/frame_info.txt", comments="#", skiprows=len(out))
    return out, nodes

def load(d):
    return read_mtx(d + "/stiffness_n_per_m.mtx"), read_mtx(d + "/mass_kg.mtx"), \
        read_mtx(d + "/damping_n_s_per_m.mtx")

def gen_eig(k, m):
    l = np.linalg.cholesky(m)
    li = np.linalg.inv(l)
    return np.linalg.eigvalsh(li @ k @ li.T)

for name in ("fixed", "lumped"):
    k, m, c = load(work + "/" + name)
    try:
        np.linalg.cholesky(k)
        spd = True
    except np.linalg.LinAlgError:
        spd = False
    check(spd, name + ": K positive definite with the base fixed (Cholesky)")
    lam = gen_eig(k, m)
    check(lam[0] > 0, name + ": lowest eigenvalue %.6g > 0" % lam[0])
    check(np.allclose(c, 0.05 * m + 1e-4 * k, rtol=1e-12, atol=1e-9 * abs(c).max()),
          name + ": C = 0.05 M + 1e-4 K")

# the seed changes the numbering only: same spectrum
k3, m3, _ = load(work + "/fixed")
k4, m4, _ = load(work + "/fixed4")
l3, l4 = gen_eig(k3, m3), gen_eig(k4, m4)
check(not np.array_equal(k3, k4), "seed 3 and 4 number the DoFs differently")
check(np.allclose(l3, l4, rtol=1e-9), "seed 3 and 4: the same eigenvalues")

for name in ("free_c", "free_l"):
    k, m, _ = load(work + "/" + name)
    meta, nodes = info(work + "/" + name)
    total = float(meta["element_mass_kg"])
    n = k.shape[0]
    for d, axis in enumerate("xyz"):
        r = np.zeros(n)
        r[d::6] = 1.0
        mass = r @ m @ r
        check(abs(mass / total - 1) < 1e-12, "%s: rigid %s translation mass %.15g = sum of "
              "element masses %.15g" % (name, axis, mass, total))
        kr = np.abs(k @ r).max()
        check(kr < 1e-9 * np.abs(k).max(), "%s: K r_%s = 0 (%.3g)" % (name, axis, kr))
    # rigid rotations through the origin: u = theta x p, rotation theta, about each axis
    for d, axis in enumerate("xyz"):
        theta = np.zeros(3)
        theta[d] = 1.0
        r = np.zeros(n)
        for row in nodes:
            dof = int(row[4])
            if dof:
                r[dof - 1:dof + 2] = np.cross(theta, row[1:4])
                r[dof + 2:dof + 5] = theta
        kr = np.abs(k @ r).max()
        check(kr < 1e-8 * np.abs(k).max(), "%s: K (rigid rotation about %s) = 0 (%.3g)"
              % (name, axis, kr))

# the cantilever column: 4 m, HEB 300 (A 1.49e-2, Iy 2.517e-4, Iz 8.563e-5), steel
k, m, _ = load(work + "/cantilever")
f = np.sqrt(gen_eig(k, m)) / (2 * np.pi)
E, rho, A, L = 210e9, 7850.0, 1.49e-2, 4.0
for inertia, which in ((8.563e-5, "weak"), (2.517e-4, "strong")):
    exact = 1.875104068711961**2 / (2 * np.pi) * np.sqrt(E * inertia / (rho * A * L**4))
    near = f[np.argmin(np.abs(f - exact))]
    check(abs(near / exact - 1) < 0.01, "cantilever %s axis: first bending %.6f Hz, "
          "Euler-Bernoulli %.6f Hz" % (which, near, exact))
check(abs(f[0] / (1.875104068711961**2 / (2 * np.pi) * np.sqrt(E * 8.563e-5 / (rho * A * L**4)))
          - 1) < 0.01, "cantilever: the lowest mode is the weak-axis bending one")
sys.exit(1 if bad else 0)
PY

# bad sizes are refused
/usr/bin/python3 "$gen" --nx 0 "$work/bad" >"$work/bad.out" 2>&1 && fail "--nx 0 accepted"
grep -q -- "--nx must be >= 1" "$work/bad.out" || fail "--nx 0: message: $(cat "$work/bad.out")"
exit $((failures > 0))
