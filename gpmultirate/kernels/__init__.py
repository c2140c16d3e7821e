"""Impulse-response kernels over continuous lag (paper eq. 16-19) and their structure.

The kernel home of the library: the lag kernels TC, DC, SS and PK
(:mod:`gpmultirate.kernels.lag`), the structure layer through which every
kernel answers for its own fast paths (:mod:`gpmultirate.kernels.structure`,
with :func:`observe`, the one walker over ``Sum``, ``Product`` and
``ConstantKernel``), the diagonal recursion of shift-scaled kernels
(:mod:`gpmultirate.kernels.recursion`), the filter form of DC
(:mod:`gpmultirate.kernels.filters`), the terms of readings at their own
instants (:mod:`gpmultirate.kernels.instants`, and the prior between integer
lags, :mod:`gpmultirate.kernels.hold`) and independent priors for several
inputs (:mod:`gpmultirate.kernels.inputs`).

A new kernel subclasses :class:`StructuredKernel` and, to get a fast path,
returns a structured term from :meth:`StructuredKernel.observed` (readings on
the integer lags) and :meth:`StructuredKernel.observed_at_instants`
(readings between them); see the "Adding a kernel" guide.
"""

from gpmultirate.kernels.inputs import (
    BlockTerm,
    PerInputKernel,
    input_kernels,
    kernel_for_inputs,
    like_inputs,
)
from gpmultirate.kernels.lag import (
    DC,
    PK,
    SS,
    TC,
    LagKernel,
    check_lags,
    resonance_summands,
    without_resonances,
)
from gpmultirate.kernels.structure import (
    LowRankTerm,
    ObservedTerm,
    Role,
    StructuredKernel,
    observe,
    rescaled,
)

__all__ = [
    "BlockTerm",
    "DC",
    "PK",
    "PerInputKernel",
    "SS",
    "TC",
    "LagKernel",
    "LowRankTerm",
    "ObservedTerm",
    "Role",
    "StructuredKernel",
    "check_lags",
    "input_kernels",
    "kernel_for_inputs",
    "like_inputs",
    "observe",
    "rescaled",
    "resonance_summands",
    "without_resonances",
]
