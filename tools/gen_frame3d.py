#!/usr/bin/env python3
"""Writes a 3-D frame building of Euler-Bernoulli 3-D beam elements as Matrix Market files.

Column lines on an NX x NY grid (spacing --bay-x-m, --bay-y-m), NZ storeys of height
--storey-m; at every floor level beams join neighbouring column lines in x and in y (the slabs,
modelled as beams). Every member is cut into --elements-per-member two-node elements of 12 DoFs
(6 per node: ux uy uz rx ry rz, SI units, rotations in rad). The base nodes are fixed (their
DoFs removed) unless --free-base; the remaining nodes are numbered at random (--seed), as an FE
code's numbering would be: no renumbering makes the pattern narrow.

Element matrices (local x along the member; bending about local z uses Iz, about local y Iy):
stiffness the exact Euler-Bernoulli one (axial EA/L, torsion GJ/L, cubic bending); mass either
consistent (cubic shape functions, rhoAL/420 [...], axial and torsional rhoAL/6 [2 1; 1 2] with
the polar inertia for torsion) or lumped by HRZ (rhoAL/2 per node and direction, rotary
rhoAL^3/78 about the bending axes, rho Ip L/2 in torsion). Damping: Rayleigh C = alpha M + beta K.

Usage: tools/gen_frame3d.py [--nx 4] [--ny 3] [--nz 5] [--elements-per-member 1]
                            [--mass consistent|lumped] [--seed 1] [--free-base] OUT_DIR
Writes OUT_DIR/{stiffness_n_per_m,mass_kg,damping_n_s_per_m}.mtx (coordinate real symmetric,
lower triangle, duplicates summed), OUT_DIR/frame.yaml (a configuration skeleton: interface and
forcing DoFs at roof nodes, to be completed) and OUT_DIR/frame_info.txt (sizes, total mass,
which global DoF is which node and direction). Needs python3 and numpy only.
"""
import argparse
import os
import sys

import numpy as np


def beam_matrices(length, e, g, area, iy, iz, j, rho, mass):
    """Local 12x12 stiffness and mass of a batch of elements (arrays of lengths)."""
    n = len(length)
    L = length
    k = np.zeros((n, 12, 12))
    m = np.zeros((n, 12, 12))

    def put(mat, dofs, block):
        for a, da in enumerate(dofs):
            for b, db in enumerate(dofs):
                mat[:, da, db] += block[:, a, b]

    def bar(c):  # c [[1, -1], [-1, 1]]
        return c[:, None, None] * np.array([[1.0, -1.0], [-1.0, 1.0]])

    def bending(ei):  # (v1, th1, v2, th2) with th = dv/dx
        z = np.zeros((n, 4, 4))
        c = ei / L**3
        z[:] = 0
        rows = [[12, 6, -12, 6], [6, 4, -6, 2], [-12, -6, 12, -6], [6, 2, -6, 4]]
        powers = [[0, 1, 0, 1], [1, 2, 1, 2], [0, 1, 0, 1], [1, 2, 1, 2]]
        for a in range(4):
            for b in range(4):
                z[:, a, b] = c * rows[a][b] * L ** powers[a][b]
        return z

    def bending_mass(mu):  # consistent, (v1, th1, v2, th2)
        z = np.zeros((n, 4, 4))
        rows = [[156, 22, 54, -13], [22, 4, 13, -3], [54, 13, 156, -22], [-13, -3, -22, 4]]
        powers = [[0, 1, 0, 1], [1, 2, 1, 2], [0, 1, 0, 1], [1, 2, 1, 2]]
        for a in range(4):
            for b in range(4):
                z[:, a, b] = mu * L / 420 * rows[a][b] * L ** powers[a][b]
        return z

    flip = np.diag([1.0, -1.0, 1.0, -1.0])  # in the x-z plane theta_y = -dw/dx
    put(k, [0, 6], bar(e * area / L))
    put(k, [3, 9], bar(g * j / L))
    put(k, [1, 5, 7, 11], bending(e * iz))
    put(k, [2, 4, 8, 10], flip @ bending(e * iy) @ flip)
    mu = rho * area
    if mass == "consistent":
        pair = np.array([[2.0, 1.0], [1.0, 2.0]]) / 6
        put(m, [0, 6], (mu * L)[:, None, None] * pair)
        put(m, [3, 9], (rho * (iy + iz) * L)[:, None, None] * pair)
        put(m, [1, 5, 7, 11], bending_mass(mu))
        put(m, [2, 4, 8, 10], flip @ bending_mass(mu) @ flip)
    else:
        for node in (0, 6):
            for d in range(3):
                m[:, node + d, node + d] = mu * L / 2
            m[:, node + 3, node + 3] = rho * (iy + iz) * L / 2
            m[:, node + 4, node + 4] = mu * L**3 / 78
            m[:, node + 5, node + 5] = mu * L**3 / 78
    return k, m


def rotations(axis):
    """Rows: the local x, y, z unit vectors in global coordinates, per element."""
    ex = axis / np.linalg.norm(axis, axis=1)[:, None]
    ref = np.tile([0.0, 0.0, 1.0], (len(ex), 1))
    vertical = np.abs(ex[:, 2]) > 0.9
    ref[vertical] = [1.0, 0.0, 0.0]  # columns: local y along global x
    ey = np.cross(ref, ex)
    ey /= np.linalg.norm(ey, axis=1)[:, None]
    ez = np.cross(ex, ey)
    return np.stack([ex, ey, ez], axis=1)


def build(args):
    per = args.elements_per_member
    nodes = {}  # (grid x, grid y, sub-height index) or beam interior keys -> node index
    coords = []

    def node(key, xyz):
        if key not in nodes:
            nodes[key] = len(coords)
            coords.append(xyz)
        return nodes[key]

    def col_node(ix, iy, level):  # level: 0..nz*per, column sub-nodes
        return node(("c", ix, iy, level),
                    (ix * args.bay_x_m, iy * args.bay_y_m, level * args.storey_m / per))

    elements = []  # (node a, node b, kind) kind 0 column, 1 beam
    for ix in range(args.nx):
        for iy in range(args.ny):
            for level in range(args.nz * per):
                elements.append((col_node(ix, iy, level), col_node(ix, iy, level + 1), 0))
    for storey in range(1, args.nz + 1):
        level = storey * per
        for direction in (0, 1):
            for ix in range(args.nx - (direction == 0)):
                for iy in range(args.ny - (direction == 1)):
                    a = col_node(ix, iy, level)
                    jx, jy = ix + (direction == 0), iy + (direction == 1)
                    b = col_node(jx, jy, level)
                    chain = [a]
                    pa, pb = np.array(coords[a]), np.array(coords[b])
                    for s in range(1, per):
                        chain.append(node(("b", ix, iy, storey, direction, s),
                                          tuple(pa + (pb - pa) * s / per)))
                    chain.append(b)
                    for s in range(per):
                        elements.append((chain[s], chain[s + 1], 1))
    coords = np.array(coords)
    elements = np.array(elements)
    return nodes, coords, elements


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("out_dir")
    p.add_argument("--nx", type=int, default=4)
    p.add_argument("--ny", type=int, default=3)
    p.add_argument("--nz", type=int, default=5)
    p.add_argument("--bay-x-m", type=float, default=6.0)
    p.add_argument("--bay-y-m", type=float, default=5.0)
    p.add_argument("--storey-m", type=float, default=3.5)
    p.add_argument("--elements-per-member", type=int, default=1)
    p.add_argument("--mass", choices=["consistent", "lumped"], default="consistent")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--free-base", action="store_true", help="keep the base nodes' DoFs")
    # steel sections (a HEB 300 column, an IPE 400 beam), rho includes the slab's share
    p.add_argument("--e-pa", type=float, default=210e9)
    p.add_argument("--g-pa", type=float, default=81e9)
    p.add_argument("--column", type=float, nargs=4, metavar=("A", "IY", "IZ", "J"),
                   default=[1.49e-2, 2.517e-4, 8.563e-5, 1.85e-6])
    p.add_argument("--beam", type=float, nargs=4, metavar=("A", "IY", "IZ", "J"),
                   default=[8.45e-3, 2.313e-4, 1.318e-5, 5.13e-7])
    p.add_argument("--rho-column-kg-m3", type=float, default=7850.0)
    p.add_argument("--rho-beam-kg-m3", type=float, default=7850.0 * 20)
    p.add_argument("--rayleigh-alpha", type=float, default=0.05, help="C = alpha M + beta K, 1/s")
    p.add_argument("--rayleigh-beta", type=float, default=1e-4, help="s")
    p.add_argument("--specimen", type=float, nargs=2, metavar=("MASS_KG", "STIFFNESS_N_PER_M"),
                   help="a two-storey lumped specimen on the rig: storeys of MASS_KG joined to "
                   "the ground, to each other and (the upper one) to ux of the interface roof "
                   "node by springs of STIFFNESS_N_PER_M; its two DoFs come last, the split "
                   "makes them physical")
    args = p.parse_args()
    for name in ("nx", "ny", "nz", "elements_per_member"):
        if getattr(args, name) < 1:
            sys.exit("gen_frame3d.py: --%s must be >= 1" % name.replace("_", "-"))

    nodes, coords, elements = build(args)
    n_nodes = len(coords)
    a, b, kind = elements[:, 0], elements[:, 1], elements[:, 2]
    axis = coords[b] - coords[a]
    length = np.linalg.norm(axis, axis=1)
    sec = np.where(kind[:, None] == 0, np.array(args.column)[None, :], np.array(args.beam)[None, :])
    rho = np.where(kind == 0, args.rho_column_kg_m3, args.rho_beam_kg_m3)
    k_loc, m_loc = beam_matrices(length, args.e_pa, args.g_pa, sec[:, 0], sec[:, 1], sec[:, 2],
                                 sec[:, 3], rho, args.mass)
    lam = rotations(axis)
    t = np.zeros((len(elements), 12, 12))
    for blk in range(4):
        t[:, 3 * blk:3 * blk + 3, 3 * blk:3 * blk + 3] = lam
    k_el = np.einsum("eji,ejk,ekl->eil", t, k_loc, t)
    m_el = np.einsum("eji,ejk,ekl->eil", t, m_loc, t)
    element_mass = float(np.sum(rho * sec[:, 0] * length))

    # DoF numbering: base nodes fixed (removed) unless --free-base, the rest in random order
    fixed = np.zeros(n_nodes, bool)
    if not args.free_base:
        fixed = np.isclose(coords[:, 2], 0.0)
    free_nodes = np.flatnonzero(~fixed)
    rng = np.random.default_rng(args.seed)
    order = rng.permutation(len(free_nodes))
    node_dof0 = -np.ones(n_nodes, np.int64)
    node_dof0[free_nodes[order]] = 6 * np.arange(len(free_nodes))
    n = 6 * len(free_nodes)

    el_dofs = np.empty((len(elements), 12), np.int64)
    for side, nd in enumerate((a, b)):
        for d in range(6):
            el_dofs[:, 6 * side + d] = np.where(node_dof0[nd] >= 0, node_dof0[nd] + d, -1)
    rows = np.repeat(el_dofs[:, :, None], 12, axis=2).ravel()
    cols = np.repeat(el_dofs[:, None, :], 12, axis=1).ravel()
    keep = (rows >= 0) & (cols >= 0) & (rows >= cols)
    rows, cols = rows[keep], cols[keep]
    key = cols * n + rows  # column-major order of the lower triangle
    uniq, inverse = np.unique(key, return_inverse=True)
    kv = np.bincount(inverse, weights=k_el.ravel()[keep], minlength=len(uniq))
    mv = np.bincount(inverse, weights=m_el.ravel()[keep], minlength=len(uniq))
    ur, uc = uniq % n, uniq // n
    # the roof node of the first and of the last column line: interface and forcing
    roof = args.nz * args.elements_per_member
    first = nodes[("c", 0, 0, roof)]
    last = nodes[("c", args.nx - 1, args.ny - 1, roof)]
    specimen = None
    if args.specimen:
        # two storeys s1, s2 (the last DoFs): ground -k- s1 -k- s2 -k- ux of the interface node
        ms, ks = args.specimen
        if not (ms > 0 and ks > 0):
            sys.exit("gen_frame3d.py: --specimen mass and stiffness must be > 0")
        tie = node_dof0[first]
        s1, s2 = n, n + 1
        n += 2
        er = np.array([s1, s2, s2, tie, s2])
        ec = np.array([s1, s1, s2, tie, tie])
        ek = np.array([2 * ks, -ks, 2 * ks, ks, -ks])
        em = np.array([ms, 0.0, ms, 0.0, 0.0])
        key = np.concatenate([uc * n + ur, ec * n + er])
        uniq, inverse = np.unique(key, return_inverse=True)
        kv = np.bincount(inverse, weights=np.concatenate([kv, ek]), minlength=len(uniq))
        mv = np.bincount(inverse, weights=np.concatenate([mv, em]), minlength=len(uniq))
        ur, uc = uniq % n, uniq // n
        specimen = (s1, s2)
    cv = args.rayleigh_alpha * mv + args.rayleigh_beta * kv
    ur, uc = ur + 1, uc + 1

    os.makedirs(args.out_dir, exist_ok=True)

    def write(name, values, what):
        path = os.path.join(args.out_dir, name)
        nz = values != 0
        with open(path + ".tmp", "w") as f:
            f.write("%%MatrixMarket matrix coordinate real symmetric\n")
            f.write("%% %s of a %d x %d x %d frame (%d DoFs), tools/gen_frame3d.py\n"
                    % (what, args.nx, args.ny, args.nz, n))
            f.write("%d %d %d\n" % (n, n, int(np.count_nonzero(nz))))
            np.savetxt(f, np.column_stack([ur[nz], uc[nz], values[nz]]),
                       fmt=["%d", "%d", "%.17g"])
        os.replace(path + ".tmp", path)

    write("stiffness_n_per_m.mtx", kv, "stiffness (N/m, N/rad, N m/rad)")
    write("mass_kg.mtx", mv, "mass (kg, kg m, kg m^2)")
    write("damping_n_s_per_m.mtx", cv, "Rayleigh damping %g M + %g K" % (args.rayleigh_alpha,
                                                                           args.rayleigh_beta))
    with open(os.path.join(args.out_dir, "frame.yaml"), "w") as f:
        f.write("# A %d x %d x %d frame of 3-D beam elements (%d DoFs), tools/gen_frame3d.py.\n"
                "# Skeleton: interface = ux of the roof node over column line (1,1); the force\n"
                "# on ux of the roof node over column line (%d,%d). Complete split and forcing.\n"
                % (args.nx, args.ny, args.nz, n, args.nx, args.ny))
        f.write("structure:\n  matrices:\n    mass_kg: mass_kg.mtx\n"
                "    damping_n_s_per_m: damping_n_s_per_m.mtx\n"
                "    stiffness_n_per_m: stiffness_n_per_m.mtx\n")
        f.write("split:\n  interface: [%d]\n" % (node_dof0[first] + 1))
        if specimen:
            f.write("  physical: [%d, %d]\n  mass_ratio: 0.5\n" % (specimen[0] + 1,
                                                                 specimen[1] + 1))
        f.write("forcing:\n  dof: %d\n  amplitude_n: 1.0\n" % (node_dof0[last] + 1))
    with open(os.path.join(args.out_dir, "frame_info.txt"), "w") as f:
        f.write("dofs %d\nnodes %d\nfree_nodes %d\nelements %d\nelement_mass_kg %.17g\n"
                "stored_entries %d\nmass %s\n" % (n, n_nodes, len(free_nodes), len(elements),
                                                   element_mass, len(uniq), args.mass))
        if specimen:
            f.write("specimen_first_dof %d\n" % (specimen[0] + 1))
        f.write("# node x_m y_m z_m first_dof (1-based; ux uy uz rx ry rz follow; 0: fixed)\n")
        for i in range(n_nodes):
            f.write("%d %.17g %.17g %.17g %d\n" % (i + 1, coords[i, 0], coords[i, 1],
                                                  coords[i, 2], node_dof0[i] + 1))
    print("gen_frame3d.py: %d DoFs, %d elements, %d stored entries -> %s"
          % (n, len(elements), len(uniq), args.out_dir))


if __name__ == "__main__":
    main()
