"""Per-frame QC of the cache: per prim, the max relative stretch, max speed, energy per unit mass
and the count of non-finite particles (dftl_warp.output.qc, docs/caches.md).

One thread per strand, reducing the maxima and counts into per-prim slots with atomics (exact in
any order); energy is written per strand and summed on the host in strand order, so that the QC
is the same bit for bit on one device or split, run after run. Accumulates in float64.
"""

import functools

import warp as wp

from ..core.layout import particle


@functools.cache
def prim_qc_kernel(scalar):
    """Kernel adding strand ``s``'s particles to the QC of its prim ``strand_member[s]``:
    ``stretch`` = max |length / rest - 1| over its segments, ``speed`` = max |v| (world, stage
    units/s), ``energy[s]`` = sum over free particles of 0.5 |v|^2 - g . (x + origin) (per unit mass),
    ``nans`` += particles with a non-finite position or velocity (left out of the others)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def prim_qc(
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        strand_member: wp.array(dtype=wp.int32),
        rest_lengths: wp.array(dtype=scalar),
        gravity: wp.vec3d,
        origin: wp.vec3d,
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        stretch: wp.array(dtype=wp.float64),
        speed: wp.array(dtype=wp.float64),
        energy: wp.array(dtype=wp.float64),
        nans: wp.array(dtype=wp.int32),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        m = strand_member[s]
        e = wp.float64(0.0)
        worst = wp.float64(0.0)
        fastest = wp.float64(0.0)
        bad = int(0)
        leader = positions[particle(base, stride, 0)]
        leader_ok = wp.isfinite(leader)
        if not leader_ok:
            bad += 1
        for i in range(1, n):
            k = particle(base, stride, i)
            x = positions[k]
            v = velocities[k]
            ok = wp.isfinite(x) and wp.isfinite(v)
            if not ok:
                bad += 1
            else:
                xd = wp.vec3d(wp.float64(x[0]), wp.float64(x[1]), wp.float64(x[2])) + origin
                vd = wp.vec3d(wp.float64(v[0]), wp.float64(v[1]), wp.float64(v[2]))
                e += wp.float64(0.5) * wp.dot(vd, vd) - wp.dot(gravity, xd)
                fastest = wp.max(fastest, wp.length(vd))
                rest = rest_lengths[k]
                if rest > scalar(0.0) and leader_ok:
                    worst = wp.max(worst, wp.abs(wp.float64(wp.length(x - leader) / rest) - wp.float64(1.0)))
            leader = x
            leader_ok = ok
        wp.atomic_max(stretch, m, worst)
        wp.atomic_max(speed, m, fastest)
        energy[s] = e  # per strand: the host sums them in strand order (deterministic, as on one device)
        if bad > 0:
            wp.atomic_add(nans, m, bad)

    return prim_qc
