"""The frequencies' spread that a fit adds to its posterior after conditioning.

A PK term tuned on the data knows its frequency and decay rate only to
within their standard deviations (``omega_std``, ``rate_std``: the Laplace
approximation of the evidence).  Put into the prior, that spread is
conditioned on the same data again and shrinks: at long lags only a tenth to
a third of its first-order effect on the response survived, and the bands
of lightly damped modes were too narrow.  A PK term with
``posterior_spread=True`` says that its spread is of the second kind: a fit
conditions on the kernel without it (:func:`conditioning_kernel`) and adds
its covariance, ``V V^T`` with ``V`` the columns of
:func:`spread_factor`, to the posterior
(:class:`~gpmultirate.covariance.SpreadPosterior`).  That is the law of
total variance to first order, with the response's change along the
frequency and the decay taken at the prior's amplitudes.

Only PK summands are read (a term of a sum, per input): the form
``kernel="auto"`` gives its terms.
"""

from __future__ import annotations

import numpy as np
from sklearn.base import clone
from sklearn.gaussian_process.kernels import Sum

from gpmultirate.kernels.inputs import PerInputKernel, input_kernels, like_inputs
from gpmultirate.kernels.lag import PK

__all__ = ["conditioning_kernel", "posterior_spread_terms", "spread_factor", "with_spreads"]


def posterior_spread_terms(kernel) -> list:
    """``[(input, path, PK)]`` of the PK summands of ``kernel`` with ``posterior_spread``.

    ``path`` is the term's name prefix in ``kernel``'s hyperparameters
    (``"k2"``, ``"input1__k1__k2"``).  A PK with ``posterior_spread`` placed
    elsewhere (inside a product) is refused: its spread could not be taken
    out of the conditioning.

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> kernel = C(1.0) * DC() + PK(omega=0.5, omega_std=0.01, posterior_spread=True)
    >>> [(k, path) for k, path, _ in posterior_spread_terms(kernel)]
    [(0, 'k2')]
    """
    several = isinstance(kernel, PerInputKernel)
    found = []
    for k, each in enumerate(input_kernels(kernel)):
        prefix = f"input{k}__" if several else ""
        found.extend((k, path, term) for path, term in _summands(each, prefix))
    reached = {id(term) for _, _, term in found}
    for value in kernel.get_params(deep=True).values():
        if (isinstance(value, PK) and value.spread_after_conditioning()
                and id(value) not in reached):
            raise ValueError(
                "kernel: a PK with posterior_spread=True must be a summand of the kernel (a "
                "term of a sum, per input), where its spread can be added after conditioning; "
                f"got {value!r} inside another kernel")
    return found


def _summands(kernel, prefix: str):
    """``(path, PK)`` of the posterior-spread PK summands of one input's kernel."""
    if isinstance(kernel, PK):
        return [(prefix.rstrip("_"), kernel)] if kernel.spread_after_conditioning() else []
    if isinstance(kernel, Sum):
        return _summands(kernel.k1, prefix + "k1__") + _summands(kernel.k2, prefix + "k2__")
    return []


def conditioning_kernel(kernel):
    """``kernel`` with the spread of its posterior-spread PK summands taken out.

    ``kernel`` itself when it has none.  The terms keep
    ``posterior_spread=True`` (with zero standard deviations), so the
    kernel's hyperparameters are in the same order.

    Examples
    --------
    >>> kernel = PK(omega=0.5, omega_std=0.01, rate_std=0.002, posterior_spread=True)
    >>> conditioning_kernel(kernel).spread()
    (0.0, 0.0)
    >>> plain = PK(omega=0.5)
    >>> conditioning_kernel(plain) is plain
    True
    """
    if not any(any(term.spread()) for _, _, term in posterior_spread_terms(kernel)):
        return kernel
    plain = {id(term): (0.0, 0.0) for _, _, term in posterior_spread_terms(kernel)}
    return with_spreads(kernel, plain)


def with_spreads(kernel, spreads: dict):
    """``kernel`` with the PK summands keyed by ``id`` in ``spreads`` given a posterior spread.

    Each such term is cloned with ``(omega_std, rate_std) = spreads[id(term)]``
    and ``posterior_spread=True``; the other summands are kept, the sums and
    the inputs' kernels rebuilt in the same order (the same hyperparameters).

    Examples
    --------
    >>> from sklearn.gaussian_process.kernels import ConstantKernel as C
    >>> from gpmultirate.kernels import DC
    >>> term = PK(omega=0.5)
    >>> spread = with_spreads(C(1.0) * DC() + term, {id(term): (0.01, 0.002)})
    >>> spread.k2.spread(), spread.k2.posterior_spread
    ((0.01, 0.002), True)
    """
    def walk(each):
        if isinstance(each, PK) and id(each) in spreads:
            w_std, r_std = spreads[id(each)]
            return clone(each).set_params(omega_std=w_std, rate_std=r_std, posterior_spread=True)
        if isinstance(each, Sum):
            return Sum(walk(each.k1), walk(each.k2))
        return each

    return like_inputs([walk(each) for each in input_kernels(kernel)], kernel)


def spread_factor(kernel, X: np.ndarray) -> np.ndarray:
    """``V`` with ``V V^T = k(X, X) - k0(X, X)``, ``k0`` the :func:`conditioning_kernel`.

    Two columns per posterior-spread PK summand (:meth:`PK.spread_columns`),
    zero on the rows of the other inputs.

    Parameters
    ----------
    kernel : sklearn Kernel
    X : ndarray of shape (n, 1) or (n, 2)
        Kernel inputs: lags, or ``(input, lag)`` pairs for a
        :class:`~gpmultirate.kernels.PerInputKernel`.

    Returns
    -------
    ndarray of shape (n, 2 r)

    Examples
    --------
    >>> import numpy as np
    >>> kernel = PK(alpha=0.8, omega=1.0, omega_std=0.05, posterior_spread=True)
    >>> X = np.arange(4.0)[:, None]
    >>> V = spread_factor(kernel, X)
    >>> bool(np.allclose(V @ V.T, kernel(X) - conditioning_kernel(kernel)(X)))
    True
    """
    X = np.asarray(X, dtype=float)
    terms = posterior_spread_terms(kernel)
    if isinstance(kernel, PerInputKernel):
        inputs, lags = X[:, 0].astype(int), X[:, 1]
    else:
        inputs, lags = np.zeros(X.shape[0], dtype=int), X[:, 0]
    V = np.zeros((X.shape[0], 2 * len(terms)))
    for j, (k, _, term) in enumerate(terms):
        rows = inputs == k
        V[rows, 2 * j:2 * j + 2] = term.spread_columns(lags[rows])
    return V
