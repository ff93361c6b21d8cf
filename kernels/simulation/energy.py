"""Per-strand energy above the hanging rest state, for the energy-growth monitor.

Per unit particle mass (J/kg), summed over a strand's free particles (float64)::

    E_avail = sum_i  |v_i|^2 / 2  -  g . (x_i - x_0)  +  |g| L_i

where ``x_0`` is the root and ``L_i`` the rest length along the strand from the root to particle
``i``. It is zero for a strand hanging straight down at rest and positive otherwise (for
an inextensible strand), whatever the world origin: the quantity is measured from the root.

The budget it is judged against counts the work of the strand's root and of the moving colliders that
can reach it (``dftl_warp/simulation/monitor.py``; the colliders' motion:
``dftl_warp/simulation/monitor_colliders.py``, with :func:`mesh_motion_kernel` for deforming meshes).
"""


import functools

import warp as wp

from ..core.layout import particle


@functools.cache
def strand_energy_func(scalar):
    """``strand_energy(base, stride, n, rest_lengths, gravity, positions, velocities) -> (available
    energy J/kg, root speed m/s, root position m (device coordinates), 1 if any position or velocity
    is not finite else 0)`` of one strand."""
    vec3 = wp.types.vector(3, scalar)

    @wp.func
    def strand_energy(base: wp.int32, stride: wp.int32, n: wp.int32, rest_lengths: wp.array(dtype=scalar),
                      gravity: wp.vec3d, positions: wp.array(dtype=vec3), velocities: wp.array(dtype=vec3)):
        g = wp.length(gravity)
        k0 = particle(base, stride, 0)
        x0 = positions[k0]
        v0 = velocities[k0]
        bad = wp.int32(0)
        if not (wp.isfinite(x0) and wp.isfinite(v0)):
            bad = 1
        e = wp.float64(0.0)
        along = wp.float64(0.0)
        for i in range(1, n):
            k = particle(base, stride, i)
            x = positions[k]
            v = velocities[k]
            if not (wp.isfinite(x) and wp.isfinite(v)):
                bad = 1
            dx = x - x0
            along += wp.float64(rest_lengths[k])
            rel = wp.vec3d(wp.float64(dx[0]), wp.float64(dx[1]), wp.float64(dx[2]))
            vd = wp.vec3d(wp.float64(v[0]), wp.float64(v[1]), wp.float64(v[2]))
            e += wp.float64(0.5) * wp.dot(vd, vd) - wp.dot(gravity, rel) + g * along
        root = wp.vec3d(wp.float64(x0[0]), wp.float64(x0[1]), wp.float64(x0[2]))
        return e, wp.float64(wp.length(v0)), root, bad

    return strand_energy


@functools.cache
def energy_budget_kernel(scalar):
    """The energy monitor's check on the device (``dftl_warp/simulation/monitor.py``: its budgets and
    records, per strand), with the totals a check reports: ``totals`` (float64, 4, zeroed by the
    caller) += (available energy of the finite strands, budget, strands over budget, strands not
    finite)."""
    vec3 = wp.types.vector(3, scalar)
    strand_energy = strand_energy_func(scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def energy_budget(
        # Model:
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        rest_lengths: wp.array(dtype=scalar),
        gravity: wp.vec3d,
        factor: wp.float64,
        # per strand: free particles, the energy floor (J/kg)
        free: wp.array(dtype=wp.float64),
        floor: wp.array(dtype=wp.float64),
        # Data in:
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        first: wp.int32,
        # per strand: how far from its root it reaches, and the potential energy of it standing straight up
        # (J/kg) that a moving collider can lift it to; per collider (the frame just simulated): a
        # sphere that held it (centre, radius) and its surface's speed (0: it did not move)
        strand_reach: wp.array(dtype=wp.float64),
        lift: wp.array(dtype=wp.float64),
        collider_center: wp.array(dtype=wp.vec3d),
        collider_reach: wp.array(dtype=wp.float64),
        collider_speed_now: wp.array(dtype=wp.float64),
        num_colliders: wp.int32,
        # Records in and out (per strand): start energy, energy when the root or a collider in reach
        # last moved, root position, fastest root speed, largest energy / budget, 1 once over budget,
        # fastest collider in reach
        start: wp.array(dtype=wp.float64),
        moved_energy: wp.array(dtype=wp.float64),
        root_position: wp.array(dtype=wp.vec3d),
        root_speed: wp.array(dtype=wp.float64),
        worst_ratio: wp.array(dtype=wp.float64),
        unstable: wp.array(dtype=wp.int32),
        collider_speed: wp.array(dtype=wp.float64),
        # Data out: this check's energy, budget and non-finite flag per strand, and the totals
        energy: wp.array(dtype=wp.float64),
        budget: wp.array(dtype=wp.float64),
        not_finite: wp.array(dtype=wp.int32),
        totals: wp.array(dtype=wp.float64),
    ):
        s = wp.tid()
        e, speed, root, bad = strand_energy(strand_base[s], strand_stride[s], strand_count[s], rest_lengths, gravity,
                                            positions, velocities)
        if not wp.isfinite(e):
            bad = 1
        if bad == 0:
            root_speed[s] = wp.max(root_speed[s], speed)
        if first != 0:
            e0 = e
            if bad != 0:
                e0 = wp.float64(0.0)
            start[s] = e0
            moved_energy[s] = e0
            root_position[s] = root
        moved = speed > wp.float64(0.0) or root[0] != root_position[s][0] or root[1] != root_position[s][1] \
            or root[2] != root_position[s][2]
        # the fastest moving collider whose sphere came within the strand's reach of its root (the
        # root's way since the last check added)
        pushed = wp.float64(0.0)
        travel = wp.length(root - root_position[s])
        for c in range(num_colliders):
            if collider_speed_now[c] > pushed and wp.length(root - collider_center[c]) <= (
                    collider_reach[c] + strand_reach[s] + travel):
                pushed = collider_speed_now[c]
        if pushed > wp.float64(0.0):
            moved = True
        if moved and bad == 0:
            moved_energy[s] = e
            collider_speed[s] = wp.max(collider_speed[s], pushed)
        root_position[s] = root
        u = root_speed[s] + collider_speed[s]
        gross = start[s] + floor[s] + wp.float64(2.0) * free[s] * u * u
        if collider_speed[s] > wp.float64(0.0):
            gross += lift[s]
        b = factor * wp.min(gross, moved_energy[s] + floor[s])
        over = bad != 0 or e > b
        ratio = e / wp.max(b, wp.float64(1.0e-300))
        if bad != 0:
            ratio = wp.float64(wp.inf)
        worst_ratio[s] = wp.max(worst_ratio[s], ratio)
        if over:
            unstable[s] = 1
            wp.atomic_add(totals, 2, wp.float64(1.0))
        energy[s] = e
        budget[s] = b
        not_finite[s] = bad
        if bad == 0:
            wp.atomic_add(totals, 0, e)
        else:
            wp.atomic_add(totals, 3, wp.float64(1.0))
        wp.atomic_add(totals, 1, b)

    return energy_budget


@functools.cache
def mesh_motion_kernel():
    """Kernel over a mesh collider's points (local, float32): ``out[k]`` becomes the largest
    displacement of a point since ``before`` (its points at the last check, then set to the current
    ones), ``out[k + 1]`` the largest distance of a point from the mesh's origin (atomic maxima: the
    caller zeroes ``out``)."""

    @wp.kernel(enable_backward=False, module="unique")
    def mesh_motion(points: wp.array(dtype=wp.vec3), k: wp.int32, before: wp.array(dtype=wp.vec3),
                    out: wp.array(dtype=wp.float64)):
        i = wp.tid()
        p = points[i]
        wp.atomic_max(out, k, wp.float64(wp.length(p - before[i])))
        wp.atomic_max(out, k + 1, wp.float64(wp.length(p)))
        before[i] = p

    return mesh_motion
