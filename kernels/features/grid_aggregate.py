"""A grid node's density and momentum added once per warp: lanes that write the same node sum
their values first (warp-aggregated atomics), and one of them writes.

The per-strand splat (``grid_strands.py``) runs the strands of a warp side by side; their roots
are neighbours (the particle-major layout puts each warp's strands in the Morton order of their
roots), so at a dense groom most lanes of a warp write the same grid node at the same time. The
GPU's atomics then serialise on that node: on an H200 the splat took 19x the bare step at 1M
strands (docs/benchmarks.md). On CUDA, :func:`node_add_func`'s function finds the lanes of the
warp that write the same node (``match.any.sync``), sums their density and momentum with warp
shuffles (a butterfly when the whole warp writes one node, else the group's leader gathering its
members in lane order), and the group's first lane writes the sums with 4 atomics. On the CPU,
and for float64 grids, each thread writes its own values with 4 atomics. The sums are the same up
to floating-point rounding (their order differs, as the order of a GPU's atomics already does).
"""

import functools
from typing import Any

import warp as wp

#: the lanes of the warp that write node (i, j, k) (``peers``) and this lane's index (``lane``)
_PEERS = """
#if defined(__CUDA_ARCH__)
    unsigned int active = __activemask();
    int key = (i * ny + j) * nz + k;
    unsigned int peers;
    asm volatile("match.any.sync.b32 %0, %1, %2;" : "=r"(peers) : "r"(key), "r"(active));
    unsigned int lane;
    asm volatile("mov.u32 %0, %%laneid;" : "=r"(lane));
"""

_SNIPPET = _PEERS + """    float r = rho;
    float x = momentum_value[0];
    float y = momentum_value[1];
    float z = momentum_value[2];
    if (peers == 0xffffffffu) {
        for (int d = 16; d > 0; d >>= 1) {
            r += __shfl_xor_sync(peers, r, d);
            x += __shfl_xor_sync(peers, x, d);
            y += __shfl_xor_sync(peers, y, d);
            z += __shfl_xor_sync(peers, z, d);
        }
    } else if (peers != (1u << lane)) {
        float sr = 0.0f, sx = 0.0f, sy = 0.0f, sz = 0.0f;
        unsigned int rest = peers;
        while (rest) {
            int src = __ffs((int)rest) - 1;
            rest &= rest - 1u;
            sr += __shfl_sync(peers, r, src);
            sx += __shfl_sync(peers, x, src);
            sy += __shfl_sync(peers, y, src);
            sz += __shfl_sync(peers, z, src);
        }
        r = sr; x = sx; y = sy; z = sz;
    }
    if ((int)lane == __ffs((int)peers) - 1) {
        wp::atomic_add(density, i, j, k, r);
        wp::atomic_add(momentum, i, j, k, wp::vec_t<3, wp::float32>(x, y, z));
    }
#else
    wp::atomic_add(density, i, j, k, rho);
    wp::atomic_add(momentum, i, j, k, momentum_value);
#endif
"""


_DENSITY_SNIPPET = _PEERS + """    float r = rho;
    if (peers == 0xffffffffu) {
        for (int d = 16; d > 0; d >>= 1) {
            r += __shfl_xor_sync(peers, r, d);
        }
    } else if (peers != (1u << lane)) {
        float sr = 0.0f;
        unsigned int rest = peers;
        while (rest) {
            int src = __ffs((int)rest) - 1;
            rest &= rest - 1u;
            sr += __shfl_sync(peers, r, src);
        }
        r = sr;
    }
    if ((int)lane == __ffs((int)peers) - 1) {
        wp::atomic_add(density, i, j, k, r);
    }
#else
    wp::atomic_add(density, i, j, k, rho);
#endif
"""


@wp.func_native(_DENSITY_SNIPPET)
def _density_add_f32(density: wp.array3d(dtype=wp.float32), i: int, j: int, k: int, ny: int, nz: int,
                     rho: wp.float32): ...


@wp.func
def _density_add_plain(density: wp.array3d(dtype=Any), i: int, j: int, k: int, ny: int, nz: int, rho: Any):
    """Each thread's own atomic (float32 and float64; ``ny``, ``nz`` unused)."""
    wp.atomic_add(density, i, j, k, rho)


@functools.cache
def density_add_func(scalar, aggregate: bool = True):
    """``density_add(density, i, j, k, ny, nz, rho)``: :func:`node_add_func` for the density alone
    (the grid's every-substep splat between full rebuilds, ``hair_hair.Grid``)."""
    return _density_add_f32 if scalar == wp.float32 and aggregate else _density_add_plain


@wp.func_native(_SNIPPET)
def _node_add_f32(density: wp.array3d(dtype=wp.float32), momentum: wp.array3d(dtype=wp.vec3f), i: int, j: int,
                  k: int, ny: int, nz: int, rho: wp.float32, momentum_value: wp.vec3f): ...


@wp.func
def _node_add_plain(density: wp.array3d(dtype=Any), momentum: wp.array3d(dtype=Any), i: int, j: int, k: int,
                    ny: int, nz: int, rho: Any, momentum_value: Any):
    """Each thread's own 4 atomics (float32 and float64; ``ny``, ``nz`` unused)."""
    wp.atomic_add(density, i, j, k, rho)
    wp.atomic_add(momentum, i, j, k, momentum_value)


@functools.cache
def node_add_func(scalar, aggregate: bool = True):
    """``node_add(density, momentum, i, j, k, ny, nz, rho, m)``: add density ``rho`` (particles)
    and momentum ``m`` (m/s) to node ``(i, j, k)`` of a grid of ``(nx, ny, nz)`` nodes (on CUDA in
    float32 aggregated over the lanes of a warp that write the same node; ``aggregate`` False: each
    thread writes its own values, for measurements)."""
    return _node_add_f32 if scalar == wp.float32 and aggregate else _node_add_plain
