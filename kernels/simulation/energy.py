"""Per-strand energy above the hanging rest state, for the energy-growth monitor.

Per unit particle mass (J/kg), summed over a strand's free particles (float64)::

    E_avail = sum_i  |v_i|^2 / 2  -  g . (x_i - x_0)  +  |g| L_i

where ``x_0`` is the root and ``L_i`` the rest length along the strand from the root to particle
``i``. It is zero for a strand hanging straight down at rest and positive otherwise (for
an inextensible strand), whatever the world origin: the quantity is measured from the root.

An elastic strand (``dftl_warp/solvers/elastic.py``) also stores energy in its bending and twist: a
strand bent by a collider and let go turns it into motion. Its available energy is the solver's
total (``RodGroup.energy`` in ``dftl_warp/solvers/elastic_rest.py``, the quantity the scheme
conserves), per unit of the strand's mean particle mass ``m = sum_i m_i / n``::

    E_avail = ( sum_i m_i (|v_i|^2 / 2 - g . (x_i - x_0) + |g| L_i)  +  E_bend  +  E_twist ) / m
    E_bend  = sum_j W_j / 2 |(Dx)_j - F_j b_j|^2,   E_twist = sum_j G_j (3 - tr(F_j^T F_{j-1} Qb_j))

less ``E_rest / m``, the elastic energy of its rest shape (with inverse statics, the bending moments
that hold a styled strand up: energy it cannot give away at rest; the measure is then the DFTL one at
the authored shape, and it is clamped at 0 where the strand finds a state of less energy), with the
solver's masses ``m_i``, bending weights ``W_j``, rest curvatures ``b_j``, twist couplings
``G_j``, rest rotations ``Qb_j``, the State's frames ``F_j`` and clamp ghost ``x_{-1}`` (``F_{-1}``
the root frame: the clamp's rotation, then the minimal rotation onto the ghost's direction, as the
step's); a straight strand's frames carry no force and no twist energy. For a strand of equal
particle masses the first sum is ``m`` times the DFTL quantity above, so both are in J/kg of the
same scale (the budgets' ``n`` particles).

The budget it is judged against counts the work of the strand's root and of the moving colliders that
can reach it (``dftl_warp/simulation/monitor.py``; the colliders' motion:
``dftl_warp/simulation/monitor_colliders.py``, with :func:`mesh_motion_kernel` for deforming meshes).
"""


import functools
import typing

import warp as wp

from ..core.layout import particle
from ..solvers.elastic_blocks import block_funcs


@functools.cache
def root_state_func(scalar):
    """``root_state(base, stride, positions, velocities) -> (x_0, v_0, 1 if either is not finite else
    0)``: a strand's root (with stride 0, the particle at ``base``)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.func
    def root_state(base: wp.int32, stride: wp.int32, positions: wp.array(dtype=vec3), velocities: wp.array(dtype=vec3)):
        k0 = particle(base, stride, 0)
        x0 = positions[k0]
        v0 = velocities[k0]
        bad = wp.int32(0)
        if not (wp.isfinite(x0) and wp.isfinite(v0)):
            bad = 1
        return x0, v0, bad

    return root_state


@functools.cache
def strand_energy_func(scalar):
    """``strand_energy(base, stride, n, rest_lengths, gravity, positions, velocities) -> (available
    energy J/kg, root speed m/s, root position m (device coordinates), 1 if any position or velocity
    is not finite else 0)`` of one strand."""
    vec3 = wp.types.vector(3, scalar)
    root_state = root_state_func(scalar)

    @wp.func
    def strand_energy(base: wp.int32, stride: wp.int32, n: wp.int32, rest_lengths: wp.array(dtype=scalar),
                      gravity: wp.vec3d, positions: wp.array(dtype=vec3), velocities: wp.array(dtype=vec3)):
        g = wp.length(gravity)
        x0, v0, bad = root_state(base, stride, positions, velocities)
        e = wp.float64(0.0)
        along = wp.float64(0.0)
        for i in range(1, n):
            k = particle(base, stride, i)
            x, v, blown = root_state(k, 0, positions, velocities)   # particle k's state
            bad = wp.max(bad, blown)
            dx = x - x0
            along += wp.float64(rest_lengths[k])
            rel = wp.vec3d(wp.float64(dx[0]), wp.float64(dx[1]), wp.float64(dx[2]))
            vd = wp.vec3d(wp.float64(v[0]), wp.float64(v[1]), wp.float64(v[2]))
            e += wp.float64(0.5) * wp.dot(vd, vd) - wp.dot(gravity, rel) + g * along
        root = wp.vec3d(wp.float64(x0[0]), wp.float64(x0[1]), wp.float64(x0[2]))
        return e, wp.float64(wp.length(v0)), root, bad

    return strand_energy


@functools.cache
def elastic_terms_struct(scalar, real):
    """The struct of an elastic strand's energy terms (the solver's rest data, in its computation
    precision ``real``, and the State's frames and clamp ghosts, in ``scalar``); see the module
    docstring. Per device strand: ``clamp_rotation``, the clamp's rotation from its authored pose at
    the end of the frame; ``rest_energy``, the elastic energy of its rest shape (J/kg, per unit of its
    mean particle mass)."""
    fields = dict(mass=wp.array(dtype=real), length=wp.array(dtype=real), bend=wp.array(dtype=real),
                  twist=wp.array(dtype=real), curvature=wp.array(dtype=wp.types.vector(3, real)),
                  rest_rotation=wp.array(dtype=wp.types.quaternion(real)),
                  clamp_direction=wp.array(dtype=wp.types.vector(3, real)), curved=wp.array(dtype=wp.int32),
                  clamp_rotation=wp.array(dtype=wp.types.matrix((3, 3), scalar)),
                  frames=wp.array(dtype=wp.types.quaternion(scalar)), clamps=wp.array(dtype=wp.types.vector(3, scalar)),
                  rest_energy=wp.array(dtype=wp.float64))
    name = "ElasticTerms_" + ("f64_" if scalar == wp.float64 else "f32_") + ("f64" if real == wp.float64 else "f32")
    cls = type(name, (), {"__annotations__": fields, "__module__": __name__, "__qualname__": name})
    return wp.struct(cls, module="unique")


@functools.cache
def elastic_energy_func(scalar, real):
    """``elastic_energy(s, base, stride, n, rest_lengths, gravity, positions, velocities, terms) ->
    (available energy, its elastic part, root speed, root position, not finite)``: as
    :func:`strand_energy_func`'s, with the elastic strand's energy (module docstring) of device strand
    ``s`` (``terms``: :func:`elastic_terms_struct`), computed in float64."""
    Terms = elastic_terms_struct(scalar, real)
    blocks = block_funcs(wp.float64)
    curv = blocks.curv
    between = blocks.between
    root_state = root_state_func(scalar)

    @wp.func
    def d3(v: typing.Any):
        return wp.vec3d(wp.float64(v[0]), wp.float64(v[1]), wp.float64(v[2]))

    @wp.func
    def dq(q: typing.Any):
        return wp.normalize(wp.quatd(wp.float64(q[0]), wp.float64(q[1]), wp.float64(q[2]), wp.float64(q[3])))

    @wp.func
    def root_frame(terms: Terms, s: wp.int32, root: wp.vec3d, ghost: wp.vec3d):
        """The step's root frame at the frame's end: the clamp's turn, then the minimal rotation
        from the turned clamp direction onto the ghost -> root direction."""
        m = terms.clamp_rotation[s]
        R = wp.mat33d(wp.float64(m[0, 0]), wp.float64(m[0, 1]), wp.float64(m[0, 2]),
                      wp.float64(m[1, 0]), wp.float64(m[1, 1]), wp.float64(m[1, 2]),
                      wp.float64(m[2, 0]), wp.float64(m[2, 1]), wp.float64(m[2, 2]))
        return between(R * d3(terms.clamp_direction[s]), root - ghost) * R

    @wp.func
    def elastic_energy(s: wp.int32, base: wp.int32, stride: wp.int32, n: wp.int32,
                       rest_lengths: wp.array(dtype=scalar), gravity: wp.vec3d,
                       positions: wp.array(dtype=wp.types.vector(3, scalar)),
                       velocities: wp.array(dtype=wp.types.vector(3, scalar)), terms: Terms):
        g = wp.length(gravity)
        x0, v0, bad = root_state(base, stride, positions, velocities)
        root = d3(x0)
        e = wp.float64(0.0)
        elastic = wp.float64(0.0)
        mass = wp.float64(0.0)
        along = wp.float64(0.0)
        curved = terms.curved[s] != 0
        Fprev = wp.identity(3, dtype=wp.float64)
        xm = d3(terms.clamps[s])
        if curved:
            Fprev = root_frame(terms, s, root, xm)
        xj = root
        for i in range(1, n):
            k = particle(base, stride, i)
            x, v, blown = root_state(k, 0, positions, velocities)   # particle k's state
            bad = wp.max(bad, blown)
            xp = d3(x)
            vd = d3(v)
            m = wp.float64(terms.mass[k])
            along += wp.float64(rest_lengths[k])
            mass += m
            e += m * (wp.float64(0.5) * wp.dot(vd, vd) - wp.dot(gravity, xp - root) + g * along)
            # vertex j = i - 1: bending (and twist on a curved strand), from x_{j-1}, x_j, x_{j+1}
            kj = particle(base, stride, i - 1)
            b = d3(terms.curvature[kj])
            if curved:
                F = wp.quat_to_matrix(dq(terms.frames[kj]))
                b = F * b
                rel = wp.transpose(F) * Fprev * wp.quat_to_matrix(dq(terms.rest_rotation[kj]))
                elastic += wp.float64(terms.twist[kj]) * (wp.float64(3.0) - rel[0, 0] - rel[1, 1] - rel[2, 2])
                Fprev = F
            r = curv(xm, xj, xp, wp.float64(terms.length[kj]), wp.float64(terms.length[k])) - b
            elastic += wp.float64(0.5) * wp.float64(terms.bend[kj]) * wp.dot(r, r)
            xm = xj
            xj = xp
        if n > 1:   # per unit of the mean particle mass, above the rest shape's elastic energy
            elastic = elastic * wp.float64(n - 1) / mass - terms.rest_energy[s]
            e = wp.max(e * wp.float64(n - 1) / mass + elastic, wp.float64(0.0))
        return e, elastic, wp.float64(wp.length(v0)), root, bad

    return elastic_energy


@functools.cache
def energy_budget_kernel(scalar, real=wp.float64, elastic: bool = False):
    """The energy monitor's check on the device (``dftl_warp/simulation/monitor.py``: its budgets and
    records, per strand), with the totals a check reports: ``totals`` (float64, 4, zeroed by the
    caller) += (available energy of the finite strands, budget, strands over budget, strands not
    finite). ``elastic``: the strands are the elastic solver's, their energy its total (module
    docstring), its terms in the ``terms`` argument (:func:`elastic_terms_struct` of ``scalar`` and
    the solver's computation precision ``real``; unread otherwise)."""
    vec3 = wp.types.vector(3, scalar)
    strand_energy = strand_energy_func(scalar)
    elastic_energy = elastic_energy_func(scalar, real)
    ELASTIC = bool(elastic)

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
        terms: elastic_terms_struct(scalar, real),
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
        # fastest collider in reach, largest elastic energy when the root or a collider in reach moved
        start: wp.array(dtype=wp.float64),
        moved_energy: wp.array(dtype=wp.float64),
        root_position: wp.array(dtype=wp.vec3d),
        root_speed: wp.array(dtype=wp.float64),
        worst_ratio: wp.array(dtype=wp.float64),
        unstable: wp.array(dtype=wp.int32),
        collider_speed: wp.array(dtype=wp.float64),
        stored_energy: wp.array(dtype=wp.float64),
        # Data out: this check's energy, budget and non-finite flag per strand, and the totals
        energy: wp.array(dtype=wp.float64),
        budget: wp.array(dtype=wp.float64),
        not_finite: wp.array(dtype=wp.int32),
        totals: wp.array(dtype=wp.float64),
    ):
        s = wp.tid()
        if wp.static(ELASTIC):
            e, stored, speed, root, bad = elastic_energy(s, strand_base[s], strand_stride[s], strand_count[s],
                                                         rest_lengths, gravity, positions, velocities, terms)
        else:
            e, speed, root, bad = strand_energy(strand_base[s], strand_stride[s], strand_count[s], rest_lengths,
                                                gravity, positions, velocities)
            stored = wp.float64(0.0)
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
            stored_energy[s] = wp.max(stored_energy[s], stored)
        root_position[s] = root
        u = root_speed[s] + collider_speed[s]
        gross = start[s] + floor[s] + wp.float64(2.0) * free[s] * u * u + stored_energy[s]
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
