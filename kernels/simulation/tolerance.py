"""The prior form's carried correction rescaled when the substep changes (``--tolerance``).

DFTL's prior form carries ``c = x - p`` of a step into the next prediction, ``p -= s c``
(``kernels/solvers/ftl.py``). It is a constraint force times the step squared (the seed's DFTL
analysis, eq. 15: the multiplier is ``delta / dt^2``), so when the substep goes from ``dt_old`` to
``dt_new`` between frames the same force is carried as ``c (dt_new / dt_old)^2``. Carried as it is,
a step 16 x shorter than the last applies 256 x the force for one step. Measured on the collider
scene of ``tests/test_tolerance.py`` (DFTL, float64, RMS error against 8192 substeps; 2-core CPU VM,
2026-11-24): 4 substeps for five frames then 64 gives 0.0255 carried as it is, 0.0059 rescaled
(4 throughout: 0.0215); 16 then 128 gives 0.0115 and 0.0023.
"""


import functools

import warp as wp

from ..core.layout import particle


@functools.cache
def scale_corrections_kernel(scalar):
    """Kernel multiplying every particle's carried correction by ``factor`` (one thread per strand,
    through the layout, so interleaved state buffers are touched only in their correction slots)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def scale_corrections(
        # Model:
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        # Data in:
        factor: scalar,
        # Data out:
        corrections: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        for i in range(strand_count[s]):
            k = particle(base, stride, i)
            corrections[k] = factor * corrections[k]

    return scale_corrections
