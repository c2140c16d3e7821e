r"""Kernels seen through readings at their own instants: the terms of timed readings.

Readings between the fast ticks, with an exposure and a latency
(:class:`~gpmultirate.observations.TimedConvolution`), are formed from the
impulse response at real lags.  The walker
(:func:`~gpmultirate.kernels.structure.observe`) keeps sums and constant
multiples; each leaf answers through
:meth:`~gpmultirate.kernels.StructuredKernel.observed_at_instants`:

* TC, DC and SS of one input: their values between integer lags are the
  hold's interpolation of the integer-lag ones
  (:mod:`gpmultirate.kernels.hold`), so the readings are rows on the integer
  lags (the observation's ``on_integer_lags``) and the kernels' own
  integer-lag terms apply (no term here);
* PK of one input: :class:`PKTimedTerm`, and a constant:
  :class:`ConstantTimedTerm`, of rank two and one at any lag, by their bases;
* any other kernel (products, inputs coupled, any scikit-learn kernel):
  :class:`DenseTimedTerm`, from the kernel at the real lags grouped by the
  distinct offsets, ``O(G^2 P^2)`` kernel entries for ``G`` distinct offsets
  (as cheap as on the ticks for ``G = 1``, meant for small problems
  otherwise).

The derivatives of the terms here are exact to rounding: the complex step
on the hyperparameter values.

The terms read the readings' points (their regressor rows, offsets from
their ticks and quadrature weights: ``unique_rows``, ``point_offsets``,
``point_readings``, ``point_weights``) from the observation; how those are
formed is the observation's business.
"""

from __future__ import annotations

import numpy as np

from gpmultirate.kernels.structure import ConstantTerm, ObservedTerm

__all__ = ["BLOCK_ENTRIES", "ConstantTimedTerm", "DenseTimedTerm", "PKTimedTerm"]

#: the complex step of the derivatives (relative to the value)
_STEP = 1e-30
#: kernel entries formed at once by the dense route and the cross-covariance
BLOCK_ENTRIES = 2**22


class _TimedTerm(ObservedTerm):
    """A leaf kernel seen through timed readings; subclasses provide :meth:`_build`.

    ``_build(values)`` returns the covariance of the readings for the
    hyperparameter ``values`` (real, or complex for the complex step); the
    derivative with respect to a free ``theta`` entry is
    ``Im build(value + i h) / h`` times ``d value / d theta``.
    """

    def _values(self) -> dict:
        return {h.name: float(getattr(self.kernel, h.name)) for h in self.kernel.hyperparameters}

    def _free(self):
        return [h for h in self.kernel.hyperparameters if not h.fixed]

    def _build(self, values):
        raise NotImplementedError

    def covariance(self):
        if getattr(self, "_covariance", None) is None:
            S = np.real(self._build(self._values()))
            self._covariance = 0.5 * (S + S.T)
        return self._covariance

    def _derivatives(self):
        values = self._values()
        items = []
        for h in self._free():
            step = _STEP * max(abs(values[h.name]), 1.0)
            moved = dict(values)
            moved[h.name] = values[h.name] + 1j * step
            built = self._build(moved)
            if getattr(self, "_covariance", None) is None:
                # the real part of the complex step is the value to O(step^2): no build of its own
                S = np.real(built)
                self._covariance = 0.5 * (S + S.T)
            dS = np.imag(built) / step
            transform = getattr(self.kernel, "theta_transform", None)
            chain = (values[h.name] if transform is None
                     else float(transform(h.name).derivative(values[h.name])))
            dS = chain * 0.5 * (dS + dS.T)
            items.append(dS)
        return items

    def covariance_with_derivatives(self):
        items = self._derivatives()
        return self.covariance(), items

    def covariance_with_contractor(self):
        items = self._derivatives()
        return self.covariance(), lambda W: np.array([np.sum(W * dS) for dS in items])

    def regressor_times_kernel(self):
        return self.cross_covariance(self.observation.lags).T

    def low_rank(self):
        return None

    def precision(self):
        return None


class ConstantTimedTerm(_TimedTerm):
    """A constant through timed readings: ``S = c U U^T``, ``U`` the readings of the constant 1."""

    def _readings_of_one(self) -> np.ndarray:
        """``U``, ``(M,)``: the readings of the constant response 1 (every input's rows summed)."""
        obs = self.observation
        return np.asarray(obs.gather() @ obs.unique_rows().sum(axis=1))

    def _build(self, values):
        U = self._readings_of_one()[:, None]
        D = np.array([[values["constant_value"]]])
        return (U @ D) @ U.T

    def cross_covariance(self, lags):
        """``Cov(g(lags), y) = c 1 U^T``: the constant at every lag with the readings of 1."""
        n = np.asarray(lags).shape[0]
        return np.outer(np.full(n, self._values()["constant_value"]), self._readings_of_one())

    def roles(self):
        return ConstantTerm(self.kernel, None, self.path).roles()

    def scale_roles(self):
        return [0] if self._free() else None


class PKTimedTerm(_TimedTerm):
    """PK through timed readings: ``S = U D U^T``, ``U`` the readings of its low-rank basis.

    The basis ``alpha^(x/2) cos(omega x)``, ``alpha^(x/2) sin(omega x)`` (and,
    with PK's spread, its derivative in ``lambda``, ``x`` times each; on the
    first cell the mode's step response with PK's ``hold``) read through the
    readings' separable form
    (:meth:`~gpmultirate.observations.TimedConvolution.damped_sinusoids`,
    ``O(R P)`` for the ``R`` distinct regressor rows, not the quadrature
    points times ``P``); complex hyperparameter values (the complex step of
    the derivatives) pass through it.
    """

    def _readings(self, values):
        """``(U, d)``: the readings of the basis, ``(M, r)``, and ``D``'s diagonal."""
        spread = any(self.kernel.spread())
        rate = -0.5 * np.log(values["alpha"])
        U = self.observation.damped_sinusoids(rate, values["omega"], with_lag=spread,
                                              hold=self.kernel.held())
        weights = [values["sigma1"] ** 2, values["sigma2"] ** 2]
        if spread:
            weights.extend(self.kernel._spread_weights(values))
        return U, np.array(weights)

    def _build(self, values):
        U, d = self._readings(values)
        return (U * d) @ U.T

    def cross_covariance(self, lags):
        """``Cov(g(lags), y) = V(lags) D U^T``, ``V`` the basis at ``lags`` (first column)."""
        U, d = self._readings(self._values())
        t = np.asarray(lags, dtype=float)
        t = t[:, 0] if t.ndim == 2 else t
        pairs = self.kernel.basis_derivatives(t, d.shape[0] // 2 - 1)
        return (np.column_stack([part for pair in pairs for part in pair]) * d) @ U.T


class DenseTimedTerm(_TimedTerm):
    """Any kernel through timed readings, from the kernel at the real lags, by distinct offsets."""

    def _pairs(self, eval_gradient: bool):
        obs = self.observation
        rows = obs.point_rows()
        offsets, group = np.unique(obs.point_offsets, return_inverse=True)
        group = group.reshape(-1)
        n = obs.n_points
        n_theta = self.kernel.n_dims if eval_gradient else 0
        S = np.zeros((n, n))
        dS = np.zeros((n_theta, n, n))
        members = [np.flatnonzero(group == g) for g in range(offsets.shape[0])]
        lags = [obs.point_lags(o) for o in offsets]
        for a in range(offsets.shape[0]):
            for b in range(a, offsets.shape[0]):
                ia, ib = members[a], members[b]
                if eval_gradient:
                    # scikit-learn's gradients are of k(X, X): both offsets' lags stacked
                    both = lags[a] if a == b else np.vstack([lags[a], lags[b]])
                    K, dK = self.kernel(both, eval_gradient=True)
                    size = lags[a].shape[0]
                    K, dK = K[:size, -size:], dK[:size, -size:]
                else:
                    K = self.kernel(lags[a], lags[b])
                block = rows[ia] @ K @ rows[ib].T
                S[np.ix_(ia, ib)] = block
                S[np.ix_(ib, ia)] = block.T
                for j in range(n_theta):
                    block = rows[ia] @ dK[:, :, j] @ rows[ib].T
                    dS[j][np.ix_(ia, ib)] = block
                    dS[j][np.ix_(ib, ia)] = block.T
        return S, dS

    def covariance(self):
        if getattr(self, "_covariance", None) is None:
            S, _ = self._pairs(False)
            S = self.observation.point_sum(S)
            self._covariance = 0.5 * (S + S.T)
        return self._covariance

    def _derivatives(self):
        S, dS = self._pairs(True)
        point_sum = self.observation.point_sum
        if getattr(self, "_covariance", None) is None:
            S = point_sum(S)
            self._covariance = 0.5 * (S + S.T)
        return [point_sum(d) for d in dS]
