"""Arithmetic of the sweep: fused multiply-add and reciprocal square root, the same in every kernel.

The step kernels are compiled without floating-point contraction (``fuse_fp`` off) so that every
kernel computes each value with the same roundings and the fused and unfused paths agree bitwise.
These helpers put the multiply-adds back where the sweep wants them, explicitly, so that every
kernel still rounds identically:

- ``fma(a, b, c) = a * b + c`` with a single rounding (CUDA ``__fma_rn``; on the CPU the
  compiler's ``fma`` builtin, IEEE 754 fusedMultiplyAdd);
- ``rsqrt(x) = 1 / sqrt(x)``: CUDA ``rsqrt.approx.ftz.f32`` (float32) / ``rsqrt`` (float64)
  (at most 2 / 1 units in the last place), on the CPU ``1 / sqrt(x)`` (two correctly rounded operations, within 1.5 units). It
  replaces a correctly rounded square root and division: on the H200 the fused kernels ran
  1.2x (8 particles per strand) to 1.9x (32) faster with it (a probe run on 2026-11-21, k = 8).
  The projected segment length is then exact to a
  few units in the last place instead of about one, 3e-7 relative in float32. Results differ
  between CPU and CUDA at that level; on one device every kernel agrees bitwise. The float32
  form equals ``rsqrtf`` bitwise on normal numbers and skips ``rsqrtf``'s rescaling of subnormal
  inputs (three instructions per particle); a subnormal ``|d|^2`` counts as zero, which the
  sweep treats as a degenerate prediction either way.
"""

import warp as wp


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return __fmaf_rn(a, b, c);
#else
return __builtin_fmaf(a, b, c);
#endif
""")
def fma(a: wp.float32, b: wp.float32, c: wp.float32) -> wp.float32: ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return __fma_rn(a, b, c);
#else
return __builtin_fma(a, b, c);
#endif
""")
def fma(a: wp.float64, b: wp.float64, c: wp.float64) -> wp.float64: ...  # noqa: F811


@wp.func
def madd(a: wp.float32, b: wp.vec3f, c: wp.vec3f):
    """``a * b + c`` per component, each rounded once."""
    return wp.vec3f(fma(a, b[0], c[0]), fma(a, b[1], c[1]), fma(a, b[2], c[2]))


@wp.func
def madd(a: wp.float64, b: wp.vec3d, c: wp.vec3d):  # noqa: F811
    """``a * b + c`` per component, each rounded once."""
    return wp.vec3d(fma(a, b[0], c[0]), fma(a, b[1], c[1]), fma(a, b[2], c[2]))


@wp.func
def norm2(d: wp.vec3f):
    """``|d|^2`` with two multiply-adds."""
    return fma(d[0], d[0], fma(d[1], d[1], d[2] * d[2]))


@wp.func
def norm2(d: wp.vec3d):  # noqa: F811
    """``|d|^2`` with two multiply-adds."""
    return fma(d[0], d[0], fma(d[1], d[1], d[2] * d[2]))


@wp.func_native("""
#if defined(__CUDA_ARCH__)
float y;
asm("rsqrt.approx.ftz.f32 %0, %1;" : "=f"(y) : "f"(x));
return y;
#else
return 1.0f / sqrtf(x);
#endif
""")
def rsqrt(x: wp.float32) -> wp.float32: ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return rsqrt(x);
#else
return 1.0 / sqrt(x);
#endif
""")
def rsqrt(x: wp.float64) -> wp.float64: ...  # noqa: F811


@wp.func
def max_keep_nan(a: wp.float32, b: wp.float32):
    """The larger of ``a`` and ``b``, NaN if ``b`` is NaN: ``wp.max(a, NaN)`` is ``a``, so a
    Newton residual accumulated with ``wp.max`` read a NaN solve as converged."""
    if b > a or b != b:
        return b
    return a


@wp.func
def max_keep_nan(a: wp.float64, b: wp.float64):
    if b > a or b != b:
        return b
    return a
