"""Adding a kernel: a first-order pole, with its own fast path, in one class.

The prior ``k(t, s) = pole^(t + s)`` says that the impulse response is that of
a first-order system ``g(t) = b pole^t`` with an unknown gain ``b``
(scaled by a ``ConstantKernel``).  It has rank one: ``K = v v^T`` with
``v(t) = pole^t``.  The class below is a scikit-learn kernel (so it composes
with ``+`` and ``*`` and tunes by marginal likelihood) and answers for its
own structure through :meth:`~gpmultirate.kernels.StructuredKernel.observed`:
it returns a :class:`~gpmultirate.kernels.LowRankTerm`, so the library never
forms its ``P x P`` matrix to compute the data covariance, the gradient of
the evidence or its Fisher information.  Nothing else in the library is
edited.  The fitted model is saved and loaded back: the file names the class,
and :func:`~gpmultirate.load_model` instantiates it only when it is passed as
``kernels=[FirstOrderPole]``.

Run ``python examples/adding_a_kernel.py [--output DIR] [--quick]``.
"""

from __future__ import annotations

import argparse
import pathlib

import numpy as np
from sklearn.gaussian_process.kernels import ConstantKernel as C
from sklearn.gaussian_process.kernels import Hyperparameter, Kernel

import gpmultirate as gm
from gpmultirate import simulation as sim
from gpmultirate.kernels import DC, LowRankTerm, StructuredKernel, check_lags, observe


class FirstOrderPole(StructuredKernel, Kernel):
    r"""Rank-one prior of a first-order impulse response.

    .. math:: k(t, s) = p^{t + s}

    Parameters
    ----------
    pole : float, default=0.9
        The pole ``p`` in (0, 1].
    pole_bounds : pair of floats or "fixed", default=(1e-4, 1.0)
        Bounds for marginal-likelihood tuning.
    """

    # the pole is a decay in (0, 1]: tuned in decay-rate coordinates
    tuning_roles = {"pole": ("decay", 1.0)}

    def __init__(self, pole: float = 0.9, pole_bounds=(1e-4, 1.0)):
        self.pole = pole
        self.pole_bounds = pole_bounds

    @property
    def hyperparameter_pole(self) -> Hyperparameter:
        return Hyperparameter("pole", "numeric", self.pole_bounds)

    def __call__(self, X, Y=None, eval_gradient=False):
        """``k(X, Y)`` and, for ``Y=None``, the gradient with respect to ``log(pole)``."""
        if eval_gradient and Y is not None:
            raise ValueError("gradient can only be evaluated when Y is None")
        t = check_lags(X, "X")
        s = t if Y is None else check_lags(Y, "Y")
        exponent = np.add.outer(t, s)
        K = self.pole**exponent
        if not eval_gradient:
            return K
        if self.hyperparameter_pole.fixed:
            return K, np.empty(K.shape + (0,))
        # d p^e / d log p = e p^e
        return K, (exponent * K)[:, :, None]

    def diag(self, X) -> np.ndarray:
        """The prior variance ``p^(2 t)``."""
        return self.pole ** (2.0 * check_lags(X, "X"))

    def is_stationary(self) -> bool:
        return False

    def __repr__(self) -> str:
        return f"FirstOrderPole(pole={self.pole:.3g})"

    # ------------------------------------------------------ the fast path
    def observed(self, observation, path: str = ""):
        """``K = v v^T`` with ``v = p^t``; ``dK / d log p = [v, t v] [[0, 1], [1, 0]] [v, t v]^T``."""
        lags = observation.lags[:, 0]
        v = self.pole**lags
        weights = [] if self.hyperparameter_pole.fixed else [np.array([[0.0, 1.0], [1.0, 0.0]])]
        return LowRankTerm(
            self, observation, v[:, None], np.ones((1, 1)), (lags * v)[:, None], weights, path
        )


def save_and_load(model, path):
    """Save a fitted model with this kernel and load it back.

    A model file holds the kernel's class name and constructor parameters,
    never code: ``load_model`` rebuilds ``FirstOrderPole`` only because it is
    given the class, and refuses the file otherwise, naming the class.
    """
    gm.save_model(model, path)
    return gm.load_model(path, kernels=[FirstOrderPole])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="examples/output")
    parser.add_argument("--quick", action="store_true", help="a smaller problem")
    args = parser.parse_args(argv)
    output = pathlib.Path(args.output)
    output.mkdir(parents=True, exist_ok=True)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gpmultirate.plotting import plot_bode

    rng = np.random.default_rng(0)
    n, factor, T = (300 if args.quick else 600), 3, 0.1
    # a first-order system plus a lightly damped mode: the pole kernel takes the
    # first, DC the rest
    true_g = 0.5 * 0.9 ** np.arange(n) + sim.paper_system(T).impulse_response(n)
    u, u_val = rng.standard_normal(n), rng.standard_normal(n)
    y_fast = np.convolve(u, true_g)[:n]
    y_slow = y_fast[::factor] + 0.01 * np.std(y_fast) * rng.standard_normal(len(y_fast[::factor]))

    kernel = C(1.0) * FirstOrderPole(0.8) + C(1.0) * DC(alpha=0.95, beta=0.95)
    model = gm.FIRGaussianProcess(kernel, factor=factor, noise_level=1e-4).fit(u, y_slow)
    term = observe(model.kernel_, model.observation_)
    print("structured term of the pole kernel:", type(term.first.inner).__name__)
    print("tuned kernel:", model.kernel_)
    y_val = np.convolve(u_val, true_g)[:n]
    print(f"validation GoF {model.score(u_val, y_val):.2f} %")
    loaded = save_and_load(model, output / "adding_a_kernel.npz")
    same = np.array_equal(loaded.predict(u_val), model.predict(u_val))
    print(f"saved and loaded with kernels=[FirstOrderPole]: identical predictions {same}")

    frf = model.frequency_response(sample_time=T)
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(6, 5), layout="constrained")
    plot_bode(frf, axes=axes, label="C * FirstOrderPole + C * DC")
    fig.savefig(output / "adding_a_kernel.png", dpi=120)
    plt.close(fig)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
