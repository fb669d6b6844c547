#!/usr/bin/env python3
"""Writes a storey chain whose top leg is a finely meshed rod, as Matrix Market files.

The seed building's storeys 1-3 (masses, legs) as they are; the leg between storey 3 and the top
storey (10.74 kg) is a rod of ELEMENTS two-node elements with the seed leg's static stiffness
(45052 N/m) and damping (3.7421 N s/m) and a small distributed mass (consistent mass matrix), so
the low modes stay close to the seed's and the rod adds its own, far above. DoFs: storeys 1-3,
then the rod's inner nodes bottom up, then the top storey: 3 + ELEMENTS in all.

Usage: tools/gen_rod_chain.py [--elements 997] [--rod-mass-kg 0.1074] OUT_DIR
Writes OUT_DIR/{mass_kg,damping_n_s_per_m,stiffness_n_per_m}.mtx (coordinate real symmetric,
lower triangle).
"""
import argparse
import os

SEED_MASS_KG = [5.37, 5.37, 5.37]
SEED_DAMPING = [4.4062, 3.7979, 3.7421]
SEED_STIFFNESS = [53048.0, 45724.0, 45052.0]
TOP_MASS_KG, TOP_DAMPING, TOP_STIFFNESS = 10.74, 3.7421, 45052.0


def assemble(elements, rod_mass_kg):
    n = 3 + elements
    m, c, k = {}, {}, {}

    def add(mat, i, j, v):
        key = (max(i, j), min(i, j))  # lower triangle
        mat[key] = mat.get(key, 0.0) + v

    def leg(mat, lower, upper, v):  # a spring/dashpot between two DoFs (lower -1: ground)
        add(mat, upper, upper, v)
        if lower >= 0:
            add(mat, lower, lower, v)
            add(mat, upper, lower, -v)

    for i in range(3):
        add(m, i, i, SEED_MASS_KG[i])
        leg(c, i - 1, i, SEED_DAMPING[i])
        leg(k, i - 1, i, SEED_STIFFNESS[i])
    add(m, n - 1, n - 1, TOP_MASS_KG)
    ke, ce, me = TOP_STIFFNESS * elements, TOP_DAMPING * elements, rod_mass_kg / elements
    for e in range(elements):  # element e joins node e (storey 3 for e = 0) to node e + 1
        lo, up = 2 + e, 3 + e
        leg(k, lo, up, ke)
        leg(c, lo, up, ce)
        # consistent rod mass: me / 6 [[2, 1], [1, 2]]
        add(m, lo, lo, me / 3)
        add(m, up, up, me / 3)
        add(m, up, lo, me / 6)
    return n, m, c, k


def write(path, n, entries, what):
    with open(path + ".tmp", "w") as f:
        f.write("%%MatrixMarket matrix coordinate real symmetric\n")
        f.write("%% %s, written by tools/gen_rod_chain.py\n" % what)
        f.write("%d %d %d\n" % (n, n, len(entries)))
        for (i, j), v in sorted(entries.items(), key=lambda e: (e[0][1], e[0][0])):
            f.write("%d %d %.17g\n" % (i + 1, j + 1, v))
    os.replace(path + ".tmp", path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--elements", type=int, default=997)
    ap.add_argument("--rod-mass-kg", type=float, default=0.1074)
    ap.add_argument("out_dir")
    a = ap.parse_args()
    if a.elements < 1 or not a.rod_mass_kg > 0:
        ap.error("--elements must be >= 1 and --rod-mass-kg > 0")
    n, m, c, k = assemble(a.elements, a.rod_mass_kg)
    os.makedirs(a.out_dir, exist_ok=True)
    write(os.path.join(a.out_dir, "mass_kg.mtx"), n, m, "mass matrix, kg")
    write(os.path.join(a.out_dir, "damping_n_s_per_m.mtx"), n, c, "damping matrix, N s/m")
    write(os.path.join(a.out_dir, "stiffness_n_per_m.mtx"), n, k, "stiffness matrix, N/m")


if __name__ == "__main__":
    main()
