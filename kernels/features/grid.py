"""Hair-hair interaction on a grid (DFTL paper sec. 5, after Petrovic, Henne and Anderson 2005).

Before the sweep, every ``splat_interval``-th substep of a frame (every substep by default;
:class:`~dftl_warp.features.hair_hair.Grid`; in the substeps between, the density alone is splatted
again, into its own array, so the repulsion never lags the particles):

1. the lower corner of the hair's bounding box (atomic min), so the grid follows the hair wherever
   the roots take it: :func:`grid_bounds_kernel` (one thread per particle), or
   ``grid_strands.grid_bounds_strands_kernel`` (one per strand, the same minimum; the step's);
2. :func:`grid_splat_kernel` splats every particle's *density* (trilinear weights, in particles
   per node) and *momentum* (weight times velocity, m/s) onto the grid nodes with atomics
   (``grid_strands.grid_splat_strands_kernel``: the same sums, one thread per strand).

During the sweep, :func:`grid_sample_func` gives each free particle, at its previous position:

- the grid velocity ``v_grid`` (momentum / density, m/s), toward which ``friction`` (1/s) pulls
  its velocity: ``v += (1 - exp(-friction dt)) (v_grid - v)``;
- the gradient of the density of the *other* particles (the particle's own trilinear
  contribution removed, so an isolated particle feels nothing), down which ``repulsion``
  (m/s^2 per unit density difference across one cell) pushes it:
  ``v -= repulsion h grad(rho) dt``.

Nodes sit at ``lower + (ijk - 1) h``; particles outside the grid are neither splatted nor forced.

A groom split across devices (:mod:`dftl_warp.simulation.multi_device`) combines its parts' grids with
:func:`grid_min_kernel` (lower corners) and :func:`grid_add_kernel` (splats), so that every part
sweeps against the grid of the whole groom.
"""


import functools

import warp as wp


@functools.cache
def grid_reset_kernel(scalar):
    """Kernel (one thread): ``lower[0..2]`` <- the largest finite value, before :func:`grid_bounds_kernel`."""
    big = scalar(3.0e38)

    @wp.kernel(enable_backward=False, module="unique")
    def grid_reset(lower: wp.array(dtype=scalar)):
        lower[0] = big
        lower[1] = big
        lower[2] = big

    return grid_reset


@functools.cache
def grid_bounds_kernel(scalar):
    """Kernel: ``lower[0..2]`` <- component-wise minimum of all ``positions`` (m)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def grid_bounds(positions: wp.array(dtype=vec3), lower: wp.array(dtype=scalar)):
        k = wp.tid()
        x = positions[k]
        wp.atomic_min(lower, 0, x[0])
        wp.atomic_min(lower, 1, x[1])
        wp.atomic_min(lower, 2, x[2])

    return grid_bounds


@functools.cache
def grid_min_kernel(scalar):
    """Kernel (3 threads): ``lower[i] <- min(lower[i], other[i])`` (m), combining two bounds."""

    @wp.kernel(enable_backward=False, module="unique")
    def grid_min(other: wp.array(dtype=scalar), lower: wp.array(dtype=scalar)):
        i = wp.tid()
        lower[i] = wp.min(lower[i], other[i])

    return grid_min


@functools.cache
def grid_add_kernel(scalar):
    """Kernel (one thread per node): adds another splat's density and momentum to this grid's."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def grid_add(
        other_density: wp.array3d(dtype=scalar),
        other_momentum: wp.array3d(dtype=vec3),
        density: wp.array3d(dtype=scalar),
        momentum: wp.array3d(dtype=vec3),
    ):
        i, j, k = wp.tid()
        density[i, j, k] = density[i, j, k] + other_density[i, j, k]
        momentum[i, j, k] = momentum[i, j, k] + other_momentum[i, j, k]

    return grid_add


@functools.cache
def grid_add_density_kernel(scalar):
    """Kernel (one thread per node): adds another splat's density to this grid's."""

    @wp.kernel(enable_backward=False, module="unique")
    def grid_add_density(
        other_density: wp.array3d(dtype=scalar),
        density: wp.array3d(dtype=scalar),
    ):
        i, j, k = wp.tid()
        density[i, j, k] = density[i, j, k] + other_density[i, j, k]

    return grid_add_density


@functools.cache
def grid_cell_func(scalar):
    """``cell(x, lower, inv_h, nx, ny, nz) -> (ok, i, j, k, fx, fy, fz)``: the node cell of ``x``."""
    vec3 = wp.types.vector(3, scalar)

    @wp.func
    def grid_cell(x: vec3, lower: wp.array(dtype=scalar), inv_h: scalar, nx: int, ny: int, nz: int):
        gx = (x[0] - lower[0]) * inv_h + scalar(1.0)
        gy = (x[1] - lower[1]) * inv_h + scalar(1.0)
        gz = (x[2] - lower[2]) * inv_h + scalar(1.0)
        i = int(wp.floor(gx))
        j = int(wp.floor(gy))
        k = int(wp.floor(gz))
        ok = i >= 0 and j >= 0 and k >= 0 and i < nx - 1 and j < ny - 1 and k < nz - 1
        return ok, i, j, k, gx - scalar(i), gy - scalar(j), gz - scalar(k)

    return grid_cell


@functools.cache
def grid_splat_kernel(scalar, ahead: bool = False, density_only: bool = False):
    """Kernel splatting density (the particles' ``weights``, their hair volume fraction relative to
    the groom's rest density, per node) and momentum (weight x m/s per node) trilinearly;
    ``ahead``: each particle at ``x + lead v`` (``lead`` in s), else at ``x`` (``lead`` unused);
    ``density_only``: the density alone (``momentum`` untouched)."""
    vec3 = wp.types.vector(3, scalar)
    cell = grid_cell_func(scalar)
    one = scalar(1.0)
    AHEAD = bool(ahead)
    MOMENTUM = not density_only

    @wp.kernel(enable_backward=False, module="unique")
    def grid_splat(
        # Data in: particle positions (m) and velocities (m/s), device frame
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        # Model: each particle's weight: its hair volume fraction over the rest density's
        weights: wp.array(dtype=scalar),
        # Model: the grid (lower corner m, 1 / cell size 1/m, node counts); lead (s)
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
        p = wp.tid()
        weight = weights[p]
        x = positions[p]
        if wp.static(AHEAD):
            x = x + lead * velocities[p]
        ok, i, j, k, fx, fy, fz = cell(x, lower, inv_h, nx, ny, nz)
        if not ok:
            return
        v = vec3()
        if wp.static(MOMENTUM):
            v = velocities[p]
        for c in range(8):
            di = c & 1
            dj = (c >> 1) & 1
            dk = (c >> 2) & 1
            wx = fx if di == 1 else one - fx
            wy = fy if dj == 1 else one - fy
            wz = fz if dk == 1 else one - fz
            w = wx * wy * wz * weight
            wp.atomic_add(density, i + di, j + dj, k + dk, w)
            if wp.static(MOMENTUM):
                wp.atomic_add(momentum, i + di, j + dj, k + dk, w * v)

    return grid_splat


@functools.cache
def grid_sample_func(scalar):
    """``sample(x, own, threshold, ..., density, mass, momentum) -> (v_grid, grad_rho)``: grid
    velocity (m/s, ``momentum`` over ``mass``, the density splatted with it) and the gradient (1/m)
    of the ``density`` (relative to the rest density) of the other particles beyond ``threshold``,
    ``max(rho - threshold, 0)``, at ``x``: the sampling particle's own share (its weight ``own``
    splatted at ``x``) removed (node by node with a threshold, from the sum without); zeros
    outside the grid or where the grid is empty.
    ``mass`` empty: the momentum was splatted with ``density`` (every substep a full rebuild)."""
    vec3 = wp.types.vector(3, scalar)
    cell = grid_cell_func(scalar)
    one = scalar(1.0)
    zero = scalar(0.0)

    @wp.func
    def grid_sample(
        x: vec3,
        own: scalar,
        threshold: scalar,
        lower: wp.array(dtype=scalar),
        inv_h: scalar,
        nx: int,
        ny: int,
        nz: int,
        density: wp.array3d(dtype=scalar),
        mass: wp.array3d(dtype=scalar),
        momentum: wp.array3d(dtype=vec3),
    ):
        ok, i, j, k, fx, fy, fz = cell(x, lower, inv_h, nx, ny, nz)
        separate = mass.shape[0] > 0
        if not ok:
            return vec3(), vec3()
        rho = zero
        mom = vec3()
        grad = vec3()
        self_grad = vec3()   # the particle's own share, without a threshold (removed at the end)
        for c in range(8):
            di = c & 1
            dj = (c >> 1) & 1
            dk = (c >> 2) & 1
            wx = fx if di == 1 else one - fx
            wy = fy if dj == 1 else one - fy
            wz = fz if dk == 1 else one - fz
            sx = one if di == 1 else -one
            sy = one if dj == 1 else -one
            sz = one if dk == 1 else -one
            w = wx * wy * wz
            dw = vec3(sx * wy * wz, wx * sy * wz, wx * wy * sz) * inv_h
            node = density[i + di, j + dj, k + dk]
            if separate:
                rho += w * mass[i + di, j + dj, k + dk]
            else:
                rho += w * node
            mom += w * momentum[i + di, j + dj, k + dk]
            if threshold > zero:
                # the other particles' density at this node beyond the threshold
                grad += wp.max(node - own * w - threshold, zero) * dw
            else:
                grad += node * dw
                self_grad += w * dw
        v_grid = vec3()
        # a weighted mean of the velocities splatted near x: undefined only where (nearly) nothing was
        if rho > scalar(1.0e-6) * own:
            v_grid = mom / rho
        return v_grid, grad - own * self_grad

    return grid_sample
