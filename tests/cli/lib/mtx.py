"""The CLI tests' Matrix Market reader (coordinate real symmetric, one triangle given): the
dense matrix numpy solves against, independent of rths' own reader."""
import numpy as np


def read_mtx(path):
    with open(path) as f:
        line = f.readline()
        while line.startswith("%"):
            line = f.readline()
        n, _, _ = map(int, line.split())
        data = np.loadtxt(f, ndmin=2)
    a = np.zeros((n, n))
    i, j = data[:, 0].astype(int) - 1, data[:, 1].astype(int) - 1
    np.add.at(a, (i, j), data[:, 2])
    np.add.at(a, (j, i), np.where(i != j, data[:, 2], 0))
    return a
