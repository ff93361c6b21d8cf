"""Per-frame QC of the cache: per prim, the deepest point of its strands inside any collider, in
hair radii beyond the contact distance (dftl_warp.output.qc, docs/caches.md).

The depth is measured with the registered collider shapes' own collide functions
(:class:`~dftl_warp.kernels.features.collide.ColliderKernel`, so every shape -- sphere, ellipsoid,
capsule, box, mesh and any registered later -- is covered and no distance function is written
twice), called as the clean start calls them (``kernels/features/clean_start.py``): no continuous
test, the previous position and the leader equal to the position, rest length 0 and the previous
pose equal to the current one (the struct the host fills). The response is then the projection
alone, along the collider's outward normal, so the distance it moves the particle is exactly the
penetration of the contact distance, ``max(0, radius - d)`` (m), ``d`` the signed distance to the
surface and ``radius`` the particle's contact distance (half its hair width). Each collider is
measured on its own and the deepest kept (the step chains them, which over overlapping colliders
would add their pushes).

One thread per strand, roots left out (kinematic: where the groom puts them), non-finite positions
left out (the NaN count has them); the largest depth over the particle's hair radius (or over
``default_radius`` where the hair has no width: contact distance 0) goes into its prim's slot by an
atomic max (exact in any order). Accumulates in float64.
"""


import functools

import warp as wp

from ..core.layout import particle
from ..features.collide import COLLIDER_KERNELS, named_func


@functools.cache
def deepest_func(scalar, Features, flags: frozenset):
    """``deepest(f, x, radius) -> depth``: the largest ``max(0, radius - d)`` (m) of point ``x``
    over every device collider of the registered shapes present in ``flags``, each measured by its
    shape's collide function (see the module docstring)."""
    vec3 = wp.types.vector(3, scalar)
    kinds = [k for f, k in COLLIDER_KERNELS.items() if f in flags]
    if not kinds:
        raise ValueError("deepest_func: no collider flags")

    def kind_deepest(kind, j):
        collide_one = kind.collide(scalar, Features)
        begin, end = j, j + 1

        def deepest(f: Features, x: vec3, radius: scalar):
            depth = scalar(0.0)
            for c in range(f.collider_bounds[begin], f.collider_bounds[end]):
                y, hit = collide_one(f, c, x, x, x, scalar(0.0), False, radius)
                if hit:
                    depth = wp.max(depth, wp.length(y - x))
            return depth

        return named_func(deepest, f"qc_deepest_{kind.flag}", unique=True)

    def chain(first, second, name):
        def both(f: Features, x: vec3, radius: scalar):
            return wp.max(first(f, x, radius), second(f, x, radius))

        return named_func(both, name, unique=True)

    composed = kind_deepest(kinds[0], 0)
    name = f"qc_deepest_{kinds[0].flag}"
    for j, kind in enumerate(kinds[1:], start=1):
        name = f"{name}_{kind.flag}"
        composed = chain(composed, kind_deepest(kind, j), name)
    return composed


@functools.cache
def prim_penetration_kernel(scalar, Features, flags: frozenset):
    """Kernel putting strand ``s``'s deepest penetration into its prim ``strand_member[s]``:
    ``penetration[m]`` = max over the strand's particles but its root of ``max(0, radius - d) /
    radius`` (``radius`` = ``features.particle_radius``, or ``default_radius`` where that is 0),
    ``d`` the signed distance to the nearest collider surface at the struct's pose."""
    vec3 = wp.types.vector(3, scalar)
    deepest = deepest_func(scalar, Features, flags)

    @wp.kernel(enable_backward=False, module="unique")
    def prim_penetration(
        # Model:
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        strand_member: wp.array(dtype=wp.int32),
        features: Features,
        default_radius: wp.float64,
        # Data in:
        positions: wp.array(dtype=vec3),
        # Data out:
        penetration: wp.array(dtype=wp.float64),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        worst = wp.float64(0.0)
        for i in range(1, strand_count[s]):
            k = particle(base, stride, i)
            x = positions[k]
            if wp.isfinite(x):
                radius = features.particle_radius[k]
                depth = deepest(features, x, radius)
                if depth > scalar(0.0):
                    unit = default_radius
                    if radius > scalar(0.0):
                        unit = wp.float64(radius)
                    worst = wp.max(worst, wp.float64(depth) / unit)
        if worst > wp.float64(0.0):
            wp.atomic_max(penetration, strand_member[s], worst)

    return prim_penetration
