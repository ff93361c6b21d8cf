"""Collision of hair particles with colliders: the machinery every collider shape shares.

Every collider has a pose (a rigid transform, collider-local -> device world) for the current
substep, ``pose``, and for the previous one, ``pose_prev``; :func:`collider_pose_kernel` moves
them along a frame (translation lerp, rotation slerp, or the roots' C1 path when the frame's
poses come with their rates). Geometry lives in collider-local space.
A particle of radius ``radius`` (m, half the hair width) is in contact when its signed distance
``d`` to the surface is below ``radius``. The response:

1. *continuous* (``ccd``): the particle's path from its previous position (in the collider's
   previous pose) to its new one (in the current pose) is swept against the surface (sphere
   tracing for the analytic shapes, :func:`analytic_collide_func`; a ray query for meshes,
   ``kernels/features/mesh.py``), and the particle stops where it first crosses the surface, so a
   fast particle cannot tunnel through (a path within the contact distance that does not cross the
   surface is left to step 2: stopping it at the contact distance froze sliding particles for the
   rest of their substep, and DFTL draped on a sphere then did not converge as the substeps shrank;
   so is a path that starts in contact and ends nearest a surface facing the way it crossed:
   resting hair dips g h^2 below the surface every substep, and stopping it where it crossed
   carried it along with a moving collider whatever the friction, ``tests/test_collider_friction.py``);
2. *projection*: it is moved along the outward normal to ``d = radius``;
3. *Coulomb friction* (position-based): the tangential displacement relative to the collider
   surface during the step is removed up to ``friction * depth`` (static friction below that,
   kinetic above), ``depth`` being the projection distance of step 2;
4. *back to the rest length on the contact plane* (:func:`slide_func`): the particle goes to the
   point of the contact plane (tangent at the closest surface point, offset by ``radius``) at the
   rest length from its leader, in the direction it had from the leader -- exact for a locally
   flat surface. A particle the continuous test stopped goes through steps 3 and 4 too (on the
   contact plane where it crossed; friction from how far its path's end lay behind that plane).

The follow-the-leader sweep then restores the segment's rest length exactly
(``kernels/solvers/featured.py``), so a collision never stretches a segment. Step 4 leaves it
nothing to do on a locally flat surface: a stopped particle restored from its stop point instead
would move along the strand, below the surface by up to the rest length where the strand meets
the surface steeply (deeper than the mesh's ``depth_band``: issue 20, 126 hair radii on a
deforming body).

**Shapes are registered** (:class:`ColliderKernel`, :func:`register_collider_kernel`): each names
its kernel flag, the struct fields only it reads, and a factory of its ``collide(f, c, ...)``
function; :func:`collide_all_func` composes the registered shapes present in a flag set, in
registration order (which is also the device order of the colliders).
"""


import functools
from dataclasses import dataclass, field
from typing import Any, Callable

import warp as wp

from ..core.root_path import root_on_path

#: sphere-tracing iterations of the continuous test for analytic shapes
TRACE_ITERATIONS = 16


def transform_type(scalar):
    return wp.types.transformation(dtype=scalar)


def _no_fields(scalar) -> dict:
    return {}


@dataclass(frozen=True)
class ColliderKernel:
    """The kernel side of a collider shape.

    ``flag``: the kernel flag of the shape (``"spheres"``), also the prefix of nothing in the
    generated code but the shape's own functions. ``collide(scalar, Features)`` returns a
    ``wp.func`` ``collide(f: Features, c: int, x, x_old, leader, rest, ccd, radius) -> (x, touched)``
    for device collider ``c``, reading the shape's data from the step's struct ``f``: a particle
    that does not touch is returned bit for bit. ``fields(scalar)``: the struct fields only this
    shape reads (name -> Warp type), beyond the ones every collider has
    (:func:`collider_fields`)."""

    flag: str
    collide: Callable
    fields: Callable = field(default=_no_fields)


#: flag -> ColliderKernel, in registration order (the device order of the colliders)
COLLIDER_KERNELS: dict = {}


def register_collider_kernel(kind: ColliderKernel) -> ColliderKernel:
    """Register a collider shape's kernel side (idempotent for the same object)."""
    known = COLLIDER_KERNELS.get(kind.flag)
    if known is not None and known is not kind:
        raise ValueError(f"collider flag {kind.flag!r} is registered twice")
    COLLIDER_KERNELS[kind.flag] = kind
    return kind


def collider_flags() -> tuple:
    """Flags of the registered collider shapes, in device order."""
    return tuple(COLLIDER_KERNELS)


def collider_fields(scalar, flags) -> dict:
    """Struct fields of the colliders among ``flags``: those every collider has, the device
    collider index bounds of each present shape (``collider_bounds``), and each shape's own."""
    kinds = [k for f, k in COLLIDER_KERNELS.items() if f in flags]
    if not kinds:
        return {}
    vec3 = wp.types.vector(3, scalar)
    transform = transform_type(scalar)
    fields = dict(
        particle_radius=wp.array(dtype=scalar),
        collider_pose=wp.array(dtype=transform),
        collider_inv_pose=wp.array(dtype=transform),
        collider_inv_pose_prev=wp.array(dtype=transform),
        collider_size=wp.array(dtype=vec3),
        collider_axis=wp.array(dtype=vec3),
        collider_friction=wp.array(dtype=scalar),
        collider_iterations=int,
        # shape j of the present ones owns device colliders collider_bounds[j] .. collider_bounds[j + 1] - 1
        collider_bounds=wp.types.vector(len(kinds) + 1, wp.int32),
    )
    for kind in kinds:
        fields.update(kind.fields(scalar))
    return fields


def named_func(body, name: str, unique: bool = False):
    """``wp.func(body)`` under its own ``name`` (functions made by one factory need distinct names);
    ``unique``: in a module of its own (functions specialized to one step struct)."""
    body.__name__ = name
    body.__qualname__ = name
    return wp.func(body, module="unique") if unique else wp.func(body)


@functools.cache
def collide_all_func(scalar, Features, flags: frozenset):
    """``collide_all(f, x, x_old, leader, rest, ccd, radius) -> (x, touched)``: every registered
    shape present in ``flags``, in registration order, each over its device colliders."""
    vec3 = wp.types.vector(3, scalar)
    kinds = [k for f, k in COLLIDER_KERNELS.items() if f in flags]
    if not kinds:
        raise ValueError("collide_all_func: no collider flags")

    def kind_loop(kind, j):
        collide_one = kind.collide(scalar, Features)
        begin, end = j, j + 1

        def loop(f: Features, x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool, radius: scalar):
            touched = bool(False)
            for c in range(f.collider_bounds[begin], f.collider_bounds[end]):
                x, hit = collide_one(f, c, x, x_old, leader, rest, ccd, radius)
                touched = touched or hit
            return x, touched

        return named_func(loop, f"collide_{kind.flag}", unique=True)

    def chain(first, second, name):
        def both(f: Features, x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool, radius: scalar):
            x, touched = first(f, x, x_old, leader, rest, ccd, radius)
            x, hit = second(f, x, x_old, leader, rest, ccd, radius)
            return x, touched or hit

        return named_func(both, name, unique=True)

    composed = kind_loop(kinds[0], 0)
    name = f"collide_{kinds[0].flag}"
    for j, kind in enumerate(kinds[1:], start=1):
        name = f"{name}_{kind.flag}"
        composed = chain(composed, kind_loop(kind, j), name)
    return composed


@functools.cache
def collider_pose_kernel(scalar, curved: bool = False):
    """Kernel moving each collider to ``alpha`` of the way from ``start`` to ``end`` (the previous
    pose kept), writing both poses and their inverses.

    ``curved=False``: translation lerp, rotation slerp (``deviation_start``/``deviation_end`` are
    not read). ``curved=True``: the roots' C1 path (:mod:`dftl_warp.kernels.core.root_path`) for
    every component of the pose, ``start + alpha chord + alpha (1 - alpha) ((1 - alpha) d0 - alpha
    d1)`` with the deviations ``d = T rate - chord`` of the pose's rates at the frame's ends (the
    translation in m, the quaternion's components unitless; ``end``'s quaternion on ``start``'s
    hemisphere), the quaternion then normalised: a rotation, whose rate is continuous across frames
    as the roots' velocity is."""
    transform = transform_type(scalar)
    vec4 = wp.types.vector(4, scalar)
    quat = wp.types.quaternion(dtype=scalar)

    @wp.func
    def components(q: Any):
        return vec4(q[0], q[1], q[2], q[3])

    @wp.kernel(enable_backward=False, module="unique")
    def update_collider_poses(
        # Control: the frame's poses (device world, m) and the Hermite deviations of their rates
        pose_start: wp.array(dtype=transform),
        pose_end: wp.array(dtype=transform),
        deviation_start: wp.array(dtype=transform),
        deviation_end: wp.array(dtype=transform),
        alpha: scalar,
        # Data out: this substep's pose, the last one, and their inverses
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
        qa = wp.transform_get_rotation(a)
        qb = wp.transform_get_rotation(b)
        if wp.static(curved):
            da = deviation_start[c]
            db = deviation_end[c]
            p = root_on_path(pa, pb - pa, wp.transform_get_translation(da), wp.transform_get_translation(db), alpha)
            qv = root_on_path(components(qa), components(qb) - components(qa),
                              components(wp.transform_get_rotation(da)),
                              components(wp.transform_get_rotation(db)), alpha)
            qv = wp.normalize(qv)
            current = transform(p, quat(qv[0], qv[1], qv[2], qv[3]))
        else:
            current = transform(pa + alpha * (pb - pa), wp.quat_slerp(qa, qb, alpha))
        pose[c] = current
        inv_pose[c] = wp.transform_inverse(current)

    return update_collider_poses


def tiny_length(scalar):
    """Lengths (m) below which a direction is not normalized."""
    return scalar(1.0e-12) if scalar == wp.float64 else scalar(1.0e-7)


@functools.cache
def slide_func(scalar):
    """``slide(q, q_old, leader, rest, n, limit)``: collider-local ``q`` on a contact plane of normal
    ``n``: remove its tangential displacement from ``q_old`` up to ``limit`` (m; Coulomb friction,
    ``friction x`` the normal displacement the contact took away), then put it at ``rest`` (m) from
    ``leader`` on that plane, toward where it is (exact for a locally flat surface)."""
    vec3 = wp.types.vector(3, scalar)
    tiny = tiny_length(scalar)

    @wp.func
    def slide(q: vec3, q_old: vec3, leader: vec3, rest: scalar, n: vec3, limit: scalar):
        rel = q - q_old
        rel_t = rel - wp.dot(rel, n) * n
        lt = wp.length(rel_t)
        q_new = q
        if lt <= limit:
            q_new = q - rel_t
        else:
            q_new = q - rel_t * (limit / lt)
        # the point of the contact plane at distance rest from the leader, toward q_new
        h = wp.dot(leader - q_new, n)
        arm = q_new - leader
        arm_t = arm - wp.dot(arm, n) * n
        at = wp.length(arm_t)
        if h > -rest and h < rest and at > tiny:
            q_new = leader - h * n + wp.sqrt(rest * rest - h * h) * (arm_t / at)
        return q_new

    return slide


@functools.cache
def beyond_reach_func(scalar):
    """``beyond_reach(lead, point, n, depth, rest)``: whether the contact plane through ``point``
    (collider-local), ``depth`` behind it along its outward normal ``n``, lies farther behind the
    leader ``lead`` than the rest length ``rest``. No point at the rest length from the leader then
    clears the plane, and the rest length restored from it pulls the particle back inside along the
    segment, every round (a particle round a convex edge from its leader's face, or past a part
    thinner than a segment): the mesh, field and analytic collisions answer such a contact by where
    the segment from the leader enters the shape instead."""

    @wp.func
    def beyond_reach(lead: wp.types.vector(3, scalar), point: wp.types.vector(3, scalar),
                     n: wp.types.vector(3, scalar), depth: scalar, rest: scalar):
        return wp.dot(lead - point, n) - depth <= -rest

    return beyond_reach


@functools.cache
def respond_func(scalar):
    """``respond(q, q_old, leader, rest, dist, n, radius, mu)``: move collider-local ``q`` out to the
    contact plane ``n . y = n . q + radius - dist``, then :func:`slide_func` on it with friction
    ``mu`` x the distance moved. ``dist`` at the contact distance (``radius``) moves nothing but
    the rest length; above it, ``q`` is returned as it is."""
    vec3 = wp.types.vector(3, scalar)
    zero = scalar(0.0)
    slide = slide_func(scalar)

    @wp.func
    def respond(q: vec3, q_old: vec3, leader: vec3, rest: scalar, dist: scalar, n: vec3, radius: scalar,
                mu: scalar):
        depth = radius - dist
        if depth < zero:
            return q
        return slide(q + depth * n, q_old, leader, rest, n, mu * depth)

    return respond


@functools.cache
def analytic_collide_func(scalar, sdf_factory, name: str, entry_factory=None):
    """The collide function of an analytic shape given by its signed distance
    ``sdf(q, size, axis) -> (d, outward normal)`` (collider-local, m; ``sdf_factory(scalar)``
    makes it): ``collide(x, x_old, leader, rest, ccd, radius, pose, inv_pose, inv_pose_prev, size,
    axis, mu) -> (x, touched)``, the continuous test by sphere tracing (the SDF must be
    1-Lipschitz).

    ``entry_factory(scalar)`` makes ``entry(q, leader, size, axis) -> (found, n, d)``: where the
    segment from the leader to ``q`` enters the shape (a box's face, a smooth shape's tangent plane
    there), its outward normal and ``q``'s signed height above it. A contact (the nearest point, or
    where the path crossed) whose plane lies farther behind the leader than the rest length has no
    point at the rest length: the rest length restored from it pulled the particle back inside
    along the segment, every round (hair sliding round an edge of a moving box, 5-6 mm in; round a
    capsule, sphere or flat ellipsoid thinner than a segment, 0.6-3.1 mm). It is answered by where
    the segment enters (the side the strand rests on), as for meshes (``kernels/features/mesh.py``)."""
    vec3 = wp.types.vector(3, scalar)
    transform = transform_type(scalar)
    zero = scalar(0.0)
    tiny = tiny_length(scalar)
    sdf = sdf_factory(scalar)
    respond = respond_func(scalar)
    beyond_reach = beyond_reach_func(scalar)
    entry = entry_factory(scalar) if entry_factory is not None else None  # every shape has one
    ENTRY = entry is not None

    def body(x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool, radius: scalar, pose: transform,
             inv_pose: transform, inv_pose_prev: transform, size: vec3, axis: vec3, mu: scalar):
        q = wp.transform_point(inv_pose, x)
        dist, n = sdf(q, size, axis)
        q_old = wp.transform_point(inv_pose_prev, x_old)
        moved = bool(False)
        if ccd:
            path = q - q_old
            length = wp.length(path)
            # the SDF is 1-Lipschitz: a path ending farther than its length from the surface never crossed it
            stop = radius * scalar(1.0e-3) + rest * scalar(1.0e-4)
            if dist < length and length > tiny:
                d_old, n_old = sdf(q_old, size, axis)
                if d_old > stop:
                    # sphere-trace the relative path q_old -> q; stop where it first reaches the surface
                    # (not the contact distance: a particle sliding within the hair radius of the
                    # surface is left to the projection below; stopping it there froze it for the
                    # rest of the substep, a stickiness that grew as the substeps shrank)
                    direction = path / length
                    t = zero
                    for _ in range(TRACE_ITERATIONS):
                        d, n_t = sdf(q_old + t * direction, size, axis)
                        gap = d
                        if gap <= stop:
                            # a particle that starts in contact and ends inside, nearest a surface
                            # facing the way it crossed, is left to the projection: resting hair dips
                            # below the surface every substep (gravity alone takes it g h^2 down, more
                            # than a hair radius), and stopping it where it crossed carried it along
                            # with a moving surface whatever the friction
                            if d_old <= radius + stop and dist < zero and wp.dot(n, n_t) > zero:
                                break
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
        dist = wp.min(dist, radius)  # a stopped particle goes onto its contact plane too
        if wp.static(ENTRY):
            if beyond_reach(lead, q, n, radius - dist, rest):
                # (a face round a convex edge from the leader's, the far side of a thin part): the
                # particle leaves by where the segment from the leader enters the shape, the side
                # the strand rests on
                entered, n_in, dist_in = entry(q, lead, size, axis)
                if entered:
                    n = n_in
                    dist = dist_in
        return wp.transform_point(pose, respond(q, q_old, lead, rest, dist, n, radius, mu)), True

    return named_func(body, name)


def analytic_collider(flag: str, name: str, sdf_factory, entry_factory=None) -> ColliderKernel:
    """The :class:`ColliderKernel` of an analytic shape: its geometry in the common
    ``collider_size`` and ``collider_axis`` of each collider, its surface given by
    ``sdf_factory(scalar)`` (see :func:`analytic_collide_func`); ``name`` names its function in
    the generated code (``collide_sphere``)."""

    @functools.cache
    def collide(scalar, Features):
        vec3 = wp.types.vector(3, scalar)
        one = analytic_collide_func(scalar, sdf_factory, name, entry_factory)

        def at(f: Features, c: int, x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool, radius: scalar):
            y, hit = one(x, x_old, leader, rest, ccd, radius, f.collider_pose[c], f.collider_inv_pose[c],
                         f.collider_inv_pose_prev[c], f.collider_size[c], f.collider_axis[c], f.collider_friction[c])
            return y, hit

        return named_func(at, f"{name}_at", unique=True)

    return ColliderKernel(flag=flag, collide=collide)
