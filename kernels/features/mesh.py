"""Triangle-mesh colliders: a :class:`warp.Mesh` in collider-local coordinates (its id per collider).

The continuous test casts the particle's relative path as a ray (``wp.mesh_query_ray``) and stops
it at the first front-face crossing, on that face's contact plane, then puts it back at the rest
length on that plane (:func:`~dftl_warp.kernels.features.collide.slide_func`). The closest-point
query (``wp.mesh_query_point_sign_normal``, angle-weighted pseudo-normal sign) reaches the contact
distance plus the path plus the mesh's ``depth_band`` (m), in every collision round: a particle
outside at the step's start is at most its path below the surface, however deep an earlier round's
projection put it. A broad phase first tests the path's box against the mesh's bounds grown by the
contact distance plus the band. The response is shared
(:func:`~dftl_warp.kernels.features.collide.respond_func`).

A contact plane farther behind the particle's leader than the segment's rest length (the nearest
face, or the face the path crossed, round a convex edge from the leader's face) has no point at the
rest length: the particle put there was pulled back inside along the segment by the rest length's
restoration, every round (hair sliding round an edge of a moving box, 17-20 mm in). There, the
face the segment from the leader enters the mesh through (``entry_face``, the face the strand rests
on) answers instead; a crossing whose segment enters no face is not stopped (the path cut an edge,
ending outside) and is left to the closest-point projection.

A mesh collider with a signed distance field (``cell`` > 0 in its ``collider_sdf`` entry) is
answered by the field (``kernels/features/sdf.py``) where it can answer, and by the exact query
above where it cannot (thin parts, sharp edges, beyond the field's reach).

A deforming mesh (a point cache) moving within a frame has its points interpolated every substep
(:func:`mesh_substep_kernel`) into one of its two meshes, the other holding the previous substep's
points (``collider_mesh_prev``; 0 while the mesh does not move that way): they swap roles every
substep, so that one is written and refitted per substep. The continuous test then
carries the particle's start with the surface: the point of the previous surface nearest it (face
and barycentric coordinates) moved to where that point is now, so the path is relative to the
surface wherever it moves, as it is relative to a moving pose; friction then acts on the motion
relative to the surface too. ``collider_motion`` bounds how far any point of the mesh moved in the
substep (m): the previous surface is searched that far beyond the contact distance, band and path.
"""


import functools

import warp as wp

from .collide import (ColliderKernel, beyond_reach_func, named_func, respond_func, slide_func, tiny_length,
                      transform_type)
from .sdf import EXACT_FROM, TEST_SLOTS, WHY_EXACT, collide_sdf_func, sdf_fields


@functools.cache
def collide_mesh_func(scalar):
    """``collide_mesh(x, x_old, leader, rest, ccd, radius, pose, inv_pose, inv_pose_prev, mesh, mesh_prev,
    motion, lower, upper, depth_band, mu) -> (x, touched)``; ``lower``/``upper``: the mesh's local
    bounds over the frame (m); ``mesh_prev``: the mesh at the previous substep (0: it did not move
    within the frame) and ``motion`` (m) the farthest any of its points moved since."""
    vec3 = wp.types.vector(3, scalar)
    transform = transform_type(scalar)
    zero = scalar(0.0)
    tiny = tiny_length(scalar)
    respond = respond_func(scalar)
    slide = slide_func(scalar)
    beyond_reach = beyond_reach_func(scalar)

    @wp.func
    def entry_face(mesh: wp.uint64, q: vec3, lead: vec3):
        # the first front face the segment from the leader to q crosses: (found, its normal, q's
        # signed height above it)
        arm = q - lead
        length = wp.length(arm)
        n = vec3()
        dist = zero
        found = bool(False)
        if length > tiny:
            direction = arm / length
            hit = wp.mesh_query_ray(mesh, wp.vec3f(lead), wp.vec3f(direction), wp.float32(length))
            if hit.result and hit.sign > wp.float32(0.0):
                n = vec3(hit.normal)
                dist = (length - scalar(hit.t)) * wp.dot(direction, n)
                found = True
        return found, n, dist

    @wp.func
    def collide_mesh(x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool, radius: scalar, pose: transform,
                     inv_pose: transform, inv_pose_prev: transform, mesh: wp.uint64, mesh_prev: wp.uint64,
                     motion: scalar, lower: vec3, upper: vec3, depth_band: scalar, mu: scalar):
        q = wp.transform_point(inv_pose, x)
        q_old = wp.transform_point(inv_pose_prev, x_old)
        # broad phase: the path's box against the mesh's box grown by the contact distance and band
        # (a deforming mesh's box holds it over the whole frame)
        reach = radius + depth_band + motion
        lo = wp.min(q, q_old)
        hi = wp.max(q, q_old)
        if (lo[0] > upper[0] + reach or lo[1] > upper[1] + reach or lo[2] > upper[2] + reach
                or hi[0] < lower[0] - reach or hi[1] < lower[1] - reach or hi[2] < lower[2] - reach):
            return x, False
        if mesh_prev != wp.uint64(0):
            # the surface moved within the step: the start carried with the point of the previous
            # surface nearest it (a surface that swept past the particle is then crossed by its path)
            near = wp.mesh_query_point_no_sign(mesh_prev, wp.vec3f(q_old), wp.float32(reach + wp.length(q - q_old)))
            if near.result:
                was = vec3(wp.mesh_eval_position(mesh_prev, near.face, near.u, near.v))
                q_old = q_old + vec3(wp.mesh_eval_position(mesh, near.face, near.u, near.v)) - was
        path = q - q_old
        length = wp.length(path)
        reach = radius + depth_band
        # the query reaches as far as the path could have crossed the surface (the relative motion
        # in the collider's frame, so a moving collider is covered too), plus the band, in every
        # round: a particle outside at the step's start and inside now is at most its path below
        # the surface, whatever put it there (its motion, or an earlier round's rest-length projection)
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
                # a hit on the front of a face: the particle crossed the surface from outside. It
                # stops on the contact plane of that face (radius in front of it), where it crossed,
                # and goes back to the rest length on that plane (the follow-the-leader projection
                # from the stop point would take it along the strand, possibly deep below the
                # surface); friction: the path's end lay behind the plane by `blocked`
                # A path that starts within the contact distance of the face it hits and ends
                # inside, nearest a face that looks the same way, is left to the closest-point
                # projection below: resting hair dips below the surface every substep (gravity
                # alone takes it g h^2 down, more than a hair radius), and stopping it where it
                # crossed carried it along with a moving surface whatever the friction
                dipped = bool(False)
                if hit.result and query.result and query.sign < wp.float32(0.0):
                    start_height = -scalar(hit.t) * wp.dot(direction, vec3(hit.normal))
                    if start_height <= radius * scalar(1.001) + rest * scalar(1.0e-4):
                        dipped = wp.dot(wp.mesh_eval_face_normal(mesh, query.face), hit.normal) > wp.float32(0.0)
                if hit.result and hit.sign > wp.float32(0.0) and not dipped:
                    n = vec3(hit.normal)
                    stop = q_old + scalar(hit.t) * direction + radius * n
                    blocked = wp.dot(stop - q, n)
                    lead = wp.transform_point(inv_pose, leader)
                    if not beyond_reach(lead, stop, n, zero, rest):
                        return wp.transform_point(pose, slide(stop, q_old, lead, rest, n, mu * blocked)), True
                    # a stop beyond the leader's reach is no answer: the particle goes onto the face
                    # the segment from the leader enters the body through, if it crosses one (a
                    # path through a thin part), else the path cut an edge and the projection
                    # below places it
                    entered, n_in, dist_in = entry_face(mesh, q, lead)
                    if entered:
                        return wp.transform_point(pose, respond(q, q_old, lead, rest, dist_in, n_in, radius, mu)), True
        if not query.result:
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
        if dist >= radius:
            return x, False
        lead = wp.transform_point(inv_pose, leader)
        if beyond_reach(lead, q, n, radius - dist, rest):
            # the nearest face's contact plane (a strand sliding around an edge of a moving body,
            # 2 mm in per round before): it leaves by the face the segment from the leader enters
            # the body through, the face the strand rests on
            entered, n_in, dist_in = entry_face(mesh, q, lead)
            if entered:
                n = n_in
                dist = dist_in
        return wp.transform_point(pose, respond(q, q_old, lead, rest, dist, n, radius, mu)), True

    return collide_mesh


def mesh_fields(scalar) -> dict:
    """Struct fields of mesh colliders, per device collider: the mesh id, the previous substep's
    mesh id (0 unless it moves within the frame) and how far its points moved since (m), its depth
    band (m) and its local bounds (m); and their signed distance fields (``kernels/features/sdf.py``)."""
    vec3 = wp.types.vector(3, scalar)
    return dict(collider_mesh=wp.array(dtype=wp.uint64), collider_mesh_prev=wp.array(dtype=wp.uint64),
                collider_motion=wp.array(dtype=scalar), collider_depth_band=wp.array(dtype=scalar),
                collider_lower=wp.array(dtype=vec3), collider_upper=wp.array(dtype=vec3), **sdf_fields())


#: diagnostic: kernels built while this is True count each test of a mesh collider's field by its
#: outcome in ``sdf_tests`` (``dftl_warp.features.colliders.sdf.MeshFields.tests``); off, the
#: kernels do not touch it. Set it before the first step of a process builds its kernels.
COUNT_FIELD_TESTS = False


def _collide_mesh_at(scalar, Features):
    return _collide_mesh_at_built(scalar, Features, bool(COUNT_FIELD_TESTS))


@functools.cache
def _collide_mesh_at_built(scalar, Features, count: bool):
    vec3 = wp.types.vector(3, scalar)
    one = collide_mesh_func(scalar)
    field = collide_sdf_func(scalar)

    def collide_mesh_at(f: Features, c: int, x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool,
                        radius: scalar):
        grid = f.collider_sdf[c]
        if grid.cell > wp.float32(0.0):
            # through the collider's signed distance field, where it can answer
            z, touched, why, taken = field(x, x_old, leader, rest, ccd, radius, f.collider_pose[c],
                                           f.collider_inv_pose[c], f.collider_inv_pose_prev[c], grid,
                                           f.sdf_brick_map, f.sdf_values, f.sdf_cells, f.collider_depth_band[c],
                                           f.collider_friction[c])
            if wp.static(count):
                slot = int(wp.abs(x[0] * scalar(7.3e4) + x[1] * scalar(3.1e4) + x[2] * scalar(1.7e4))) % TEST_SLOTS
                wp.atomic_add(f.sdf_tests, why * TEST_SLOTS + slot, 1)
                # the row after the outcomes: the field's samples taken
                wp.atomic_add(f.sdf_tests, wp.static(len(WHY_EXACT)) * TEST_SLOTS + slot, taken)
            if why < EXACT_FROM:
                return z, touched
        y, hit = one(x, x_old, leader, rest, ccd, radius, f.collider_pose[c], f.collider_inv_pose[c],
                     f.collider_inv_pose_prev[c], f.collider_mesh[c], f.collider_mesh_prev[c], f.collider_motion[c],
                     f.collider_lower[c], f.collider_upper[c], f.collider_depth_band[c], f.collider_friction[c])
        return y, hit

    return named_func(collide_mesh_at, "collide_mesh_at", unique=True)


@functools.cache
def mesh_substep_kernel(scalar):
    """``(start, end, alpha_prev, alpha, frame_motion, c, write_prev, mesh, mesh_prev, points,
    points_prev, ids, prev_ids, motion)``: a deforming mesh's points ``alpha`` of the way from the
    frame's ``start`` to its ``end`` (collider-local, m) into ``points`` (those of ``mesh``), and
    with ``write_prev`` those ``alpha_prev`` of the way into ``points_prev`` (of ``mesh_prev``;
    else it holds them already: the previous substep's mesh); ``ids[c]``/``prev_ids[c]`` name the
    two meshes (read by the step at replay time, so a CUDA graph follows meshes that swap roles),
    and ``motion[c]`` is how far the points moved between the two (``frame_motion[c]``, the
    farthest any moves in the frame, times ``alpha - alpha_prev``). The frame's last substep
    (``alpha`` 1) makes ``start`` its end: a frame whose points are not set again keeps the mesh
    still."""

    @wp.kernel(enable_backward=False, module="unique")
    def mesh_substep(start: wp.array(dtype=wp.vec3), end: wp.array(dtype=wp.vec3), alpha_prev: wp.float32,
                     alpha: wp.float32, frame_motion: wp.array(dtype=wp.float32), c: int, write_prev: int,
                     mesh: wp.uint64, mesh_prev: wp.uint64, points: wp.array(dtype=wp.vec3),
                     points_prev: wp.array(dtype=wp.vec3), ids: wp.array(dtype=wp.uint64),
                     prev_ids: wp.array(dtype=wp.uint64), motion: wp.array(dtype=scalar)):
        i = wp.tid()
        a = start[i]
        b = end[i]
        if write_prev != 0:
            points_prev[i] = a + alpha_prev * (b - a)
        points[i] = a + alpha * (b - a)
        if alpha >= wp.float32(1.0):
            start[i] = b
        if i == 0:
            motion[c] = scalar(frame_motion[c] * (alpha - alpha_prev))
            ids[c] = mesh
            prev_ids[c] = mesh_prev

    return mesh_substep


MESH = ColliderKernel(flag="meshes", collide=_collide_mesh_at, fields=mesh_fields)
