"""The hair-hair grid built one strand per thread (the cheaper variants of ``grid.py``'s kernels).

:func:`grid_bounds_strands_kernel` takes each strand's minimum before its three atomics (one
atomic triple per strand instead of one per particle; the minimum is exact, so the lower corner is
bit-for-bit :func:`~dftl_warp.kernels.features.grid.grid_bounds_kernel`'s).

:func:`grid_splat_strands_kernel` walks a strand root to tip and keeps the density (weights per
node) and momentum (weight x m/s per node) of the 8 nodes of the particle's cell in registers: while the
strand stays in one cell nothing is written; when it steps to the next cell along one axis, the 4
nodes the two cells share carry over and only the 4 it leaves behind go to the grid (atomics); any
other move writes all 8. Consecutive particles of a strand are about one segment apart, so a strand
writes a node a few times instead of once per particle: 1.75 node writes per particle instead of 8
with cells of 4 segments (the default), 4.8 with cells of one segment (docs/features.md). The sums
are the per-particle splat's up to floating-point rounding (their order differs, as the order of a
GPU's atomics already does). On CUDA the lanes of a warp that write the same node sum their values
before one of them writes (``grid_aggregate.py``).

Both splat kernels (this one and ``grid.py``'s) can splat each particle where it will be ``lead``
seconds later in a straight line, ``x + lead v``: a grid rebuilt every ``k`` substeps of ``dt``
is sampled over the ``k`` substeps after it, and ``lead = (k - 1) dt / 2`` centres it on them
(:class:`~dftl_warp.features.hair_hair.Grid`). ``lead = 0`` splats ``x`` itself.
"""


import functools

import warp as wp

from ..core.layout import particle
from .grid import grid_cell_func
from .grid_aggregate import density_add_func, node_add_func


@functools.cache
def grid_bounds_strands_kernel(scalar):
    """Kernel (one thread per strand): ``lower[0..2]`` <- component-wise minimum of all
    ``positions`` (m)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def grid_bounds_strands(
        # Model: the particle layout
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        # Data in: particle positions (m, device frame)
        positions: wp.array(dtype=vec3),
        # Data out: the grid's lower corner (m), reset to +big beforehand
        lower: wp.array(dtype=scalar),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        if n == 0:
            return
        lo = positions[particle(base, stride, 0)]
        for i in range(1, n):
            lo = wp.min(lo, positions[particle(base, stride, i)])
        wp.atomic_min(lower, 0, lo[0])
        wp.atomic_min(lower, 1, lo[1])
        wp.atomic_min(lower, 2, lo[2])

    return grid_bounds_strands


#: CUDA register cap of the per-strand splat (None: the compiler's choice, 160 registers on sm_90;
#: ``scripts/profile_features.py --aux-caps`` measures others)
CUDA_MAX_REGISTERS = None


@functools.cache
def grid_splat_strands_kernel(scalar, ahead: bool = False, aggregate: bool = True, density_only: bool = False):
    """Kernel (one thread per strand) splatting density (the particles' ``weights``, their hair
    volume fraction relative to the groom's rest density, per node) and momentum (weight x m/s per
    node) trilinearly, a strand's runs through one cell summed in registers first; ``ahead``: each
    particle at ``x + lead v`` (``lead`` in s), else at ``x`` (``lead`` unused); ``aggregate``:
    node writes aggregated over a warp's lanes on CUDA (``grid_aggregate.py``; False: one write per
    thread, for measurements); ``density_only``: the density alone (``momentum`` untouched: one
    atomic per node write instead of four)."""
    AHEAD = bool(ahead)
    MOMENTUM = not density_only
    vec3 = wp.types.vector(3, scalar)
    vec8 = wp.types.vector(8, scalar)
    cell = grid_cell_func(scalar)
    node_add = node_add_func(scalar, aggregate)
    density_add = density_add_func(scalar, aggregate)
    one = scalar(1.0)
    zero = scalar(0.0)

    @wp.func
    def shifted(v: vec8, axis: int, up: bool):
        """The 8 corner values after a move of one cell along ``axis`` (up: +1, else -1): the shared
        corners move to the new cell's slots, the new ones start at zero (constant indices only,
        so the corners stay in registers)."""
        if axis == 0:
            if up:
                return vec8(v[1], zero, v[3], zero, v[5], zero, v[7], zero)
            return vec8(zero, v[0], zero, v[2], zero, v[4], zero, v[6])
        if axis == 1:
            if up:
                return vec8(v[2], v[3], zero, zero, v[6], v[7], zero, zero)
            return vec8(zero, zero, v[0], v[1], zero, zero, v[4], v[5])
        if up:
            return vec8(v[4], v[5], v[6], v[7], zero, zero, zero, zero)
        return vec8(zero, zero, zero, zero, v[0], v[1], v[2], v[3])

    @wp.kernel(enable_backward=False, module="unique", cuda_max_registers=CUDA_MAX_REGISTERS)
    def grid_splat_strands(
        # Model: the particle layout
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        # Data in: particle positions (m) and velocities (m/s), device frame
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        # Model: each particle's weight: its hair volume fraction over the rest density's
        weights: wp.array(dtype=scalar),
        # Model: the grid (lower corner m, 1 / cell size 1/m, node counts); lead (s): splat x + lead v
        lower: wp.array(dtype=scalar),
        inv_h: scalar,
        lead: scalar,
        nx: int,
        ny: int,
        nz: int,
        # Data out: density (weights per node) and momentum (weight x m/s per node),
        # zeroed beforehand
        density: wp.array3d(dtype=scalar),
        momentum: wp.array3d(dtype=vec3),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        # the 8 nodes of the current cell (corner c = di + 2 dj + 4 dk of node (ci, cj, ck))
        rho = vec8(zero)
        mx = vec8(zero)
        my = vec8(zero)
        mz = vec8(zero)
        ci = int(0)
        cj = int(0)
        ck = int(0)
        held = bool(False)
        for p in range(n):
            k = particle(base, stride, p)
            x = positions[k]
            v = vec3()
            if wp.static(MOMENTUM or AHEAD):   # the density alone at the positions reads no velocity
                v = velocities[k]
            if wp.static(AHEAD):
                x = x + lead * v
            ok, i0, j0, k0, fx, fy, fz = cell(x, lower, inv_h, nx, ny, nz)
            if ok:
                di = i0 - ci
                dj = j0 - cj
                dk = k0 - ck
                if held and (di != 0 or dj != 0 or dk != 0):
                    # the strand left the cell: after a step of one cell along one axis the 4 nodes
                    # the cells share carry over; every other node is written
                    axis = int(-1)
                    up = bool(False)
                    if dj == 0 and dk == 0 and (di == 1 or di == -1):
                        axis = 0
                        up = di == 1
                    elif di == 0 and dk == 0 and (dj == 1 or dj == -1):
                        axis = 1
                        up = dj == 1
                    elif di == 0 and dj == 0 and (dk == 1 or dk == -1):
                        axis = 2
                        up = dk == 1
                    for c in range(8):
                        keep = False
                        if axis >= 0:
                            keep = ((c >> axis) & 1) == (1 if up else 0)
                        if not keep:
                            node_i = ci + (c & 1)
                            node_j = cj + ((c >> 1) & 1)
                            node_k = ck + ((c >> 2) & 1)
                            if wp.static(MOMENTUM):
                                node_add(density, momentum, node_i, node_j, node_k, ny, nz, rho[c],
                                         vec3(mx[c], my[c], mz[c]))
                            else:
                                density_add(density, node_i, node_j, node_k, ny, nz, rho[c])
                    if axis >= 0:
                        rho = shifted(rho, axis, up)
                        if wp.static(MOMENTUM):
                            mx = shifted(mx, axis, up)
                            my = shifted(my, axis, up)
                            mz = shifted(mz, axis, up)
                    else:
                        rho = vec8(zero)
                        if wp.static(MOMENTUM):
                            mx = vec8(zero)
                            my = vec8(zero)
                            mz = vec8(zero)
                ci = i0
                cj = j0
                ck = k0
                held = True
                weight = weights[k]
                for c in range(8):
                    wx = fx if (c & 1) == 1 else one - fx
                    wy = fy if ((c >> 1) & 1) == 1 else one - fy
                    wz = fz if ((c >> 2) & 1) == 1 else one - fz
                    w = wx * wy * wz * weight
                    rho[c] = rho[c] + w
                    if wp.static(MOMENTUM):
                        mx[c] = mx[c] + w * v[0]
                        my[c] = my[c] + w * v[1]
                        mz[c] = mz[c] + w * v[2]
        if held:
            for c in range(8):
                node_i = ci + (c & 1)
                node_j = cj + ((c >> 1) & 1)
                node_k = ck + ((c >> 2) & 1)
                if wp.static(MOMENTUM):
                    node_add(density, momentum, node_i, node_j, node_k, ny, nz, rho[c], vec3(mx[c], my[c], mz[c]))
                else:
                    density_add(density, node_i, node_j, node_k, ny, nz, rho[c])

    return grid_splat_strands
