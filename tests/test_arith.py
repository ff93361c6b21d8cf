"""The sweep's arithmetic helpers (kernels/arith.py): one rounding per multiply-add, accurate rsqrt."""

import numpy as np
import pytest
import warp as wp

from dftl_warp.kernels.core.arith import fma, rsqrt


def run(scalar):
    @wp.kernel(module="unique", enable_backward=False)
    def apply(a: wp.array(dtype=scalar), fused: wp.array(dtype=scalar), inv: wp.array(dtype=scalar)):
        i = wp.tid()
        fused[i] = fma(a[i], a[i], -scalar(1.0))
        inv[i] = rsqrt(a[i])

    return apply


@pytest.mark.parametrize("precision,eps", [("float32", 2.0**-12), ("float64", 2.0**-30)])
def test_fma_rounds_once_and_rsqrt_is_accurate(precision, eps):
    scalar = wp.float32 if precision == "float32" else wp.float64
    dtype = np.dtype(precision)
    x = np.array([1.0 + eps, 2.0, 0.37, 1e-20, 3e30], dtype=dtype)
    a = wp.array(x, dtype=scalar, device="cpu")
    fused, inv = wp.zeros_like(a), wp.zeros_like(a)
    wp.launch(run(scalar), dim=len(x), inputs=[a, fused, inv], device="cpu")
    # (1 + e)^2 - 1 = 2e + e^2 exactly representable; an unfused multiply would round e^2 away
    assert fused.numpy()[0] == dtype.type(2 * eps + eps * eps)
    exact = 1.0 / np.sqrt(x.astype(np.longdouble))
    ulp = np.spacing(exact.astype(dtype)).astype(np.longdouble)
    assert (np.abs(inv.numpy().astype(np.longdouble) - exact) <= 1.5 * ulp).all()  # two roundings: sqrt, then the division
