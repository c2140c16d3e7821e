"""The hold's prior between integer lags written out, for the tests' references.

``lagrange_rows(lags, size)``: row ``i`` holds the weights of the integer lags
``0 .. size - 1`` in ``g(lags[i])``: the Lagrange polynomial through the
twelve lags ``n - 5 .. n + 6`` around ``n = floor(x)`` (the response is zero
below lag 0), a unit weight on ``n`` at an integer lag.  Written from the
definition, independently of :mod:`gpmultirate.kernels.hold`.
"""

import numpy as np


def lagrange_rows(lags, size: int) -> np.ndarray:
    lags = np.atleast_1d(np.asarray(lags, dtype=float))
    W = np.zeros((lags.shape[0], size))
    for i, x in enumerate(lags):
        n = int(np.floor(x))
        nodes = [n] if x == n else list(range(n - 5, n + 7))
        for node in nodes:
            if node >= 0:
                W[i, node] = np.prod([(x - o) / (node - o) for o in nodes if o != node])
    return W
