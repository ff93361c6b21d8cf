"""Collision of hair particles with rigid or animated colliders: spheres, capsules, boxes, meshes.

Every collider has a pose (a rigid transform, collider-local -> device world) for the current
substep, ``pose``, and for the previous one, ``pose_prev``; :func:`collider_pose_kernel` moves
them along a frame (translation lerp, rotation slerp). Geometry lives in collider-local space:

- sphere: ``size[0]`` radius (m);
- capsule: ``size[0]`` radius, ``size[1]`` half height of the core segment (m), along the unit
  local ``axis``;
- box: ``size`` half extents (m);
- mesh: a :class:`warp.Mesh` in local coordinates (its id per collider).

A particle of radius ``radius`` (m, half the hair width) is in contact when its signed distance
``d`` to the surface is below ``radius``. The response (:func:`collide_funcs`):

1. *continuous* (``ccd``): the particle's path from its previous position (in the collider's
   previous pose) to its new one (in the current pose) is swept against the surface (sphere
   tracing for the analytic shapes, a ray query for meshes), and the particle stops at the
   first contact, so a fast particle cannot tunnel through;
2. *projection*: it is moved along the outward normal to ``d = radius``;
3. *Coulomb friction* (position-based): the tangential displacement relative to the collider
   surface during the step is removed up to ``friction * depth`` (static friction below that,
   kinetic above), ``depth`` being the projection distance of step 2;
4. *back to the rest length on the contact plane*: the particle goes to the point of the contact
   plane (tangent at the closest surface point, offset by ``radius``) at the rest length from its
   leader, in the direction it had from the leader -- exact for a locally flat surface.

The follow-the-leader sweep then restores the segment's rest length exactly (see
``kernels/featured.py``), so a collision never stretches a segment; the residual penetration on
curved surfaces is what the iterations leave (measured in ``tests/test_features.py``).
"""


import functools

import warp as wp

#: sphere-tracing iterations of the continuous test for analytic shapes
TRACE_ITERATIONS = 16


def transform_type(scalar):
    return wp.types.transformation(dtype=scalar)


@functools.cache
def collider_pose_kernel(scalar):
    """Kernel moving each collider to ``start`` -> ``end`` at ``alpha`` (the previous pose kept),
    writing both poses and their inverses."""
    vec3 = wp.types.vector(3, scalar)
    transform = transform_type(scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def update_collider_poses(
        pose_start: wp.array(dtype=transform),
        pose_end: wp.array(dtype=transform),
        alpha: scalar,
        pose: wp.array(dtype=transform),
        pose_prev: wp.array(dtype=transform),
        inv_pose: wp.array(dtype=transform),
        inv_pose_prev: wp.array(dtype=transform),
    ):
        c = wp.tid()
        previous = pose[c]
        pose_prev[c] = previous
        inv_pose_prev[c] = wp.transform_inverse(previous)
        a = pose_start[c]
        b = pose_end[c]
        pa = wp.transform_get_translation(a)
        pb = wp.transform_get_translation(b)
        q = wp.quat_slerp(wp.transform_get_rotation(a), wp.transform_get_rotation(b), alpha)
        current = transform(pa + alpha * (pb - pa), q)
        pose[c] = current
        inv_pose[c] = wp.transform_inverse(current)

    return update_collider_poses


@functools.cache
def collide_funcs(scalar):
    """``(collide_sphere, collide_capsule, collide_box, collide_mesh)`` for ``scalar`` precision.

    Each returns the particle's new position (device world space, m) and whether it touched; a
    particle that did not touch is returned unchanged, bit for bit."""
    vec3 = wp.types.vector(3, scalar)
    transform = transform_type(scalar)
    zero = scalar(0.0)
    one = scalar(1.0)
    tiny = scalar(1.0e-12) if scalar == wp.float64 else scalar(1.0e-7)

    @wp.func
    def respond(q: vec3, q_old: vec3, leader: vec3, rest: scalar, dist: scalar, n: vec3, radius: scalar,
                mu: scalar):
        """Move ``q`` (collider-local) out to the contact plane ``n . y = n . q + radius - dist``,
        apply friction, then put it back at ``rest`` from ``leader`` on that plane."""
        depth = radius - dist
        if depth <= zero:
            return q
        q_new = q + depth * n
        rel = q_new - q_old
        rel_t = rel - wp.dot(rel, n) * n
        lt = wp.length(rel_t)
        limit = mu * depth
        if lt <= limit:
            q_new = q_new - rel_t
        else:
            q_new = q_new - rel_t * (limit / lt)
        # the point of the contact plane at distance rest from the leader, toward q_new
        h = wp.dot(leader - q_new, n)
        arm = q_new - leader
        arm_t = arm - wp.dot(arm, n) * n
        at = wp.length(arm_t)
        if h > -rest and h < rest and at > tiny:
            q_new = leader - h * n + wp.sqrt(rest * rest - h * h) * (arm_t / at)
        return q_new

    @wp.func
    def sphere_sdf(q: vec3, size: vec3, axis: vec3):
        d = wp.length(q)
        n = vec3(zero, one, zero)
        if d > tiny:
            n = q / d
        return d - size[0], n

    @wp.func
    def capsule_sdf(q: vec3, size: vec3, axis: vec3):
        a = wp.clamp(wp.dot(q, axis), -size[1], size[1])
        r = q - a * axis
        d = wp.length(r)
        n = vec3(zero, one, zero)
        if d > tiny:
            n = r / d
        return d - size[0], n

    @wp.func
    def box_sdf(q: vec3, size: vec3, axis: vec3):
        e = vec3(wp.abs(q[0]) - size[0], wp.abs(q[1]) - size[1], wp.abs(q[2]) - size[2])
        s = vec3(wp.sign(q[0]), wp.sign(q[1]), wp.sign(q[2]))
        outside = vec3(wp.max(e[0], zero), wp.max(e[1], zero), wp.max(e[2], zero))
        lo = wp.length(outside)
        if lo > zero:
            return lo, wp.cw_mul(s, outside) / lo
        # inside: the nearest face
        if e[0] >= e[1] and e[0] >= e[2]:
            return e[0], vec3(s[0], zero, zero)
        if e[1] >= e[2]:
            return e[1], vec3(zero, s[1], zero)
        return e[2], vec3(zero, zero, s[2])

    def make_analytic(sdf):
        """The three analytic colliders share one body; each is its own func (distinct names)."""

        def body(x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool, radius: scalar, pose: transform,
                 inv_pose: transform, inv_pose_prev: transform, size: vec3, axis: vec3, mu: scalar):
            q = wp.transform_point(inv_pose, x)
            dist, n = sdf(q, size, axis)
            q_old = wp.transform_point(inv_pose_prev, x_old)
            moved = bool(False)
            if ccd:
                path = q - q_old
                length = wp.length(path)
                # the SDF is 1-Lipschitz: a path ending farther than its length from contact never touched
                if dist - radius < length and length > tiny:
                    d_old, n_old = sdf(q_old, size, axis)
                    if d_old > radius:
                        # sphere-trace the relative path q_old -> q; stop at the first contact
                        direction = path / length
                        t = zero
                        for _ in range(TRACE_ITERATIONS):
                            d, n_t = sdf(q_old + t * direction, size, axis)
                            gap = d - radius
                            if gap <= radius * scalar(1.0e-3) + scalar(1.0e-6):
                                q = q_old + t * direction
                                dist, n = sdf(q, size, axis)
                                moved = True
                                break
                            t = t + gap
                            if t >= length:
                                break
            if dist >= radius and not moved:
                return x, False
            lead = wp.transform_point(inv_pose, leader)
            return wp.transform_point(pose, respond(q, q_old, lead, rest, dist, n, radius, mu)), True

        return body

    def analytic_func(sdf, name):
        body = make_analytic(sdf)
        body.__name__ = name
        body.__qualname__ = f"collide_funcs.<locals>.{name}"
        return wp.func(body)

    collide_sphere = analytic_func(sphere_sdf, "collide_sphere")
    collide_capsule = analytic_func(capsule_sdf, "collide_capsule")
    collide_box = analytic_func(box_sdf, "collide_box")

    @wp.func
    def collide_mesh(x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool, radius: scalar, pose: transform,
                     inv_pose: transform, inv_pose_prev: transform, mesh: wp.uint64, lower: vec3, upper: vec3,
                     depth_band: scalar, mu: scalar):
        q = wp.transform_point(inv_pose, x)
        q_old = wp.transform_point(inv_pose_prev, x_old)
        # broad phase: the path's box against the mesh's box grown by the contact distance
        reach = radius + depth_band
        lo = wp.min(q, q_old)
        hi = wp.max(q, q_old)
        if (lo[0] > upper[0] + reach or lo[1] > upper[1] + reach or lo[2] > upper[2] + reach
                or hi[0] < lower[0] - reach or hi[1] < lower[1] - reach or hi[2] < lower[2] - reach):
            return x, False
        moved = bool(False)
        path = q - q_old
        length = wp.length(path)
        # the query reaches as far as the path could have crossed the surface (the relative
        # motion in the collider's frame, so a moving collider is covered too), plus the band
        if ccd:
            reach = reach + length
        query = wp.mesh_query_point_sign_normal(mesh, wp.vec3f(q), wp.float32(reach))
        if ccd:
            # distance from q to the surface (at least reach when nothing was found): a path shorter
            # than it cannot have crossed the surface, so the ray is cast only when it could have
            clearance = reach
            if query.result:
                clearance = wp.length(q - vec3(wp.mesh_eval_position(mesh, query.face, query.u, query.v)))
                if query.sign < wp.float32(0.0):
                    clearance = zero
            if length > tiny and length > clearance - radius:
                direction = path / length
                hit = wp.mesh_query_ray(mesh, wp.vec3f(q_old), wp.vec3f(direction), wp.float32(length))
                # a hit on the front of a face: the particle crossed the surface from outside
                if hit.result and hit.sign > wp.float32(0.0):
                    q = q_old + scalar(hit.t) * direction + radius * vec3(hit.normal)
                    moved = True
                    query = wp.mesh_query_point_sign_normal(mesh, wp.vec3f(q), wp.float32(reach))
        if not query.result:
            if moved:
                return wp.transform_point(pose, q), True
            return x, False
        closest = vec3(wp.mesh_eval_position(mesh, query.face, query.u, query.v))
        r = q - closest
        d = wp.length(r)
        n = vec3(wp.mesh_eval_face_normal(mesh, query.face))
        if d > tiny:
            n = r / d
        dist = d
        if query.sign < wp.float32(0.0):
            dist = -d
            n = -n
            if d <= tiny:
                n = vec3(wp.mesh_eval_face_normal(mesh, query.face))
        if dist >= radius and not moved:
            return x, False
        lead = wp.transform_point(inv_pose, leader)
        return wp.transform_point(pose, respond(q, q_old, lead, rest, dist, n, radius, mu)), True

    return collide_sphere, collide_capsule, collide_box, collide_mesh
