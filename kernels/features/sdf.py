"""Signed distance fields of triangle-mesh colliders: a narrow band of float32 distances around the
surface, in bricks of 8 x 8 x 8 cells, rebuilt from the mesh on the device whenever its points
change, sampled trilinearly per particle per substep.

Layout (collider-local coordinates, m): a brick map (one int32 per brick of the collider's grid:
``>= 0`` the brick's slot in the pool, :data:`FAR_BRICK` no surface within the band,
:data:`OVERFLOW_BRICK` needed but the pool was full) and a pool of bricks, each with its 9^3 nodes
(``values``: signed distances, each node queried once, the last layer copied from the brick that
owns it; nodes beyond the band hold ``band``) and the state of its 8^3 cells
(``cells``): :data:`FAR` (a corner lies beyond the band: the cell is at least ``reach`` from the
surface), :data:`ANSWERS` (every corner in the band and the estimated interpolation error within
``tolerance``), :data:`EXACT` (the field cannot answer: the caller queries the mesh).

The error estimate of a cell (:func:`cell_states_kernel`): trilinear interpolation of a C2 field
errs by at most ``h^2 / 8 * sum_a max |d_aa|`` over the cell (``h`` the cell size); ``d_aa`` is
estimated from the exact gradients at the corners (the unit direction from the closest surface
point) as the change of the gradient's ``a`` component along axis ``a`` across the cell divided by
``h``: ``err = h / 8 * sum_a max over the 4 edges along a |g_a(end) - g_a(start)|``. Near thin
parts, sharp edges, open boundaries and the medial axis the corners' gradients disagree and the
estimate exceeds the tolerance: those cells are :data:`EXACT`.
"""


import functools
import math

import warp as wp

from .collide import beyond_reach_func, respond_func, slide_func, tiny_length, transform_type

#: cells per brick edge
BRICK = 8
#: nodes per brick edge (the last layer is shared with the next brick and stored in both)
NODES = BRICK + 1
BRICK_NODES = NODES * NODES * NODES
BRICK_CELLS = BRICK * BRICK * BRICK

#: cell states
FAR = 0
ANSWERS = 1
EXACT = 2
#: brick map entries that are not slots
FAR_BRICK = -1
OVERFLOW_BRICK = -2

#: counters per outcome in ``sdf_tests`` (a test adds to one of them, picked from its position, so
#: that the GPU's atomics spread over several addresses)
TEST_SLOTS = 64
#: how a particle's test of a field ended (``collide_sdf``'s last result): below :data:`EXACT_FROM`
#: the field answered (after one sample, the path's two ends, a trace along the path, or the two
#: ends' distances covering the whole path); from it on, the reason it went to the exact mesh query
WHY_EXACT = (
    "answered by the field: one sample (the path's end)",
    "answered by the field: two samples (the path's ends)",
    "answered by the field: traced along the path",
    "answered by the field: the ends' distances clear the whole path",
    "exact query: contact distance + depth band beyond the field's reach",
    "exact query: the path's end in a cell the field cannot answer",
    "exact query: the path's start in a cell the field cannot answer",
    "exact query: the path's end beyond the band, not traced",
    "exact query: from contact to where the field cannot say it stayed on the same side",
    "exact query: trace not concluded (grazing, behind the surface, or an unanswerable cell on the way)",
    "exact query: the contact plane lies farther behind the leader than the rest length (round an edge)",
)
EXACT_FROM = 4

#: how the continuous test uses the path's end: 0 not at all (the trace from the start decides), 1
#: the two ends' clearances answer a path they cover before any trace, 2 also at every step of the
#: trace (its rest covered by the step's clearance and the end's)
PATH_BOUNDS = 2
#: over-relaxed sphere tracing (Keinert et al. 2014): steps of RELAXATION times the clearance while
#: consecutive samples' clearances overlap, back to the plain step where they do not
RELAXATION = 1.6
#: steps of the trace through a field before the exact query decides (a sample is cheaper than an
#: exact query, and a grazing path needs many)
FIELD_TRACE_ITERATIONS = 64

SQRT3 = math.sqrt(3.0)
#: half the diagonal of a brick, in cells (a little more, for rounding)
BRICK_HALF_DIAGONAL = wp.constant(wp.float32(4.0 * SQRT3 * 1.0001))


@wp.struct
class SdfGrid:
    """One collider's field (collider-local, m). ``cell`` 0: the collider has no field."""

    #: position of node (0, 0, 0)
    origin: wp.vec3f
    cell: wp.float32
    inv_cell: wp.float32
    #: nodes farther than ``band`` from the surface hold no distance
    band: wp.float32
    #: the field answers up to this distance from the surface (band - sqrt(3) cell)
    reach: wp.float32
    #: the largest estimated interpolation error of an answering cell
    tolerance: wp.float32
    #: bricks per axis
    bricks: wp.vec3i
    map_offset: wp.int32
    pool_offset: wp.int32
    #: 1: the grid covers the whole band this frame (outside it is far); 0: outside it is EXACT
    complete: wp.int32


@wp.func
def _box_distance(p: wp.vec3f, lo: wp.vec3f, hi: wp.vec3f):
    e = wp.max(wp.max(lo - p, p - hi), wp.vec3f(0.0))
    return wp.length(e)


@wp.func
def sdf_sample(g: SdfGrid, brick_map: wp.array(dtype=wp.int32), values: wp.array(dtype=wp.float32),
               cells: wp.array(dtype=wp.uint8), q: wp.vec3f):
    """``(state, d, n)`` at collider-local ``q``: ANSWERS with the trilinear distance ``d`` (m)
    and the unit gradient ``n``; FAR with ``d`` a lower bound of the distance (``reach``, or more
    outside the grid), taken as outside; EXACT (ask the mesh)."""
    zero = wp.vec3f(0.0)
    u = (q - g.origin) * g.inv_cell
    fx = wp.floor(u[0])
    fy = wp.floor(u[1])
    fz = wp.floor(u[2])
    ix = int(fx)
    iy = int(fy)
    iz = int(fz)
    nbx = g.bricks[0]
    nby = g.bricks[1]
    nbz = g.bricks[2]
    if ix < 0 or iy < 0 or iz < 0 or ix >= nbx * 8 or iy >= nby * 8 or iz >= nbz * 8:
        if g.complete == 0:
            return EXACT, wp.float32(0.0), zero
        top = g.origin + wp.vec3f(float(nbx * 8), float(nby * 8), float(nbz * 8)) * g.cell
        return FAR, g.reach + _box_distance(q, g.origin, top), zero
    bx = ix // 8
    by = iy // 8
    bz = iz // 8
    slot = brick_map[g.map_offset + (bx * nby + by) * nbz + bz]
    if slot == FAR_BRICK:
        return FAR, g.reach, zero
    if slot < 0:
        return EXACT, wp.float32(0.0), zero
    lx = ix - bx * 8
    ly = iy - by * 8
    lz = iz - bz * 8
    brick = g.pool_offset + slot
    state = int(cells[brick * 512 + (lx * 8 + ly) * 8 + lz])
    if state == FAR:
        return FAR, g.reach, zero
    if state != ANSWERS:
        return EXACT, wp.float32(0.0), zero
    b = brick * 729 + (lx * 9 + ly) * 9 + lz
    v000 = values[b]
    v001 = values[b + 1]
    v010 = values[b + 9]
    v011 = values[b + 10]
    v100 = values[b + 81]
    v101 = values[b + 82]
    v110 = values[b + 90]
    v111 = values[b + 91]
    tx = u[0] - fx
    ty = u[1] - fy
    tz = u[2] - fz
    sx = 1.0 - tx
    sy = 1.0 - ty
    sz = 1.0 - tz
    # along z, then y, then x
    c00 = sz * v000 + tz * v001
    c01 = sz * v010 + tz * v011
    c10 = sz * v100 + tz * v101
    c11 = sz * v110 + tz * v111
    c0 = sy * c00 + ty * c01
    c1 = sy * c10 + ty * c11
    d = sx * c0 + tx * c1
    gx = c1 - c0
    gy = sx * (c01 - c00) + tx * (c11 - c10)
    gz = (sx * (sy * (v001 - v000) + ty * (v011 - v010)) + tx * (sy * (v101 - v100) + ty * (v111 - v110)))
    grad = wp.vec3f(gx, gy, gz) * g.inv_cell
    norm = wp.length(grad)
    if norm < 1.0e-3:
        return EXACT, wp.float32(0.0), zero
    return ANSWERS, d, grad / norm


@functools.cache
def collide_sdf_func(scalar):
    """``collide_sdf(x, x_old, leader, rest, ccd, radius, pose, inv_pose, inv_pose_prev, grid,
    brick_map, values, cells, depth_band, mu) -> (x, touched, why, taken)``: the collision of one
    particle with one mesh collider through its field, which ended as ``WHY_EXACT[why]``: below
    :data:`EXACT_FROM` the field answered; from it on it could not (the caller runs the exact mesh
    query instead, and ``x``, ``touched`` mean nothing).

    Contact: the particle is in contact where the sampled distance is below ``radius``; the
    response is the shared one (:func:`~dftl_warp.kernels.features.collide.respond_func`) along
    the field's unit gradient. The continuous test sphere-traces the relative path through the
    field from a start outside the contact distance, as for the analytic shapes: far cells step by
    their lower bound, answering cells by the sampled gap, and the particle stops at the first
    contact, on the contact plane there, and goes back to the rest length on that plane
    (:func:`~dftl_warp.kernels.features.collide.slide_func`; friction from how far the path's end
    lay behind it). The whole particle goes to the exact query (its ray decides) when the trace
    meets an EXACT cell, finds itself below the contact distance by more than twice the tolerance
    without touching (reached from behind the surface), or reaches neither a contact nor the path's
    end within ``FIELD_TRACE_ITERATIONS`` steps (a grazing path); and when a path that could have reached
    the surface ends beyond the band untraced (from contact, or in a round without the continuous
    test): a far sample's side is unknown, and the exact query reaches the whole path below the
    surface. A contact (the trace's stop or the end's) whose plane lies farther behind the leader
    than the rest length goes to the exact query too: no point at the rest length clears that plane
    (the particle round a convex edge from its leader's face), and the rest length restored from it
    pulled the particle back inside along the segment every round (a box moved through hair at 1-2
    m/s, 11-13 mm in); the exact query answers by the face the segment from the leader enters the
    body through (``kernels/features/mesh.py``). This costs one dot product per contact.
    The field is used only while ``radius + depth_band`` stays within its reach (the clean-start
    push-out and the QC ask for any depth and get the exact query)."""
    vec3 = wp.types.vector(3, scalar)
    transform = transform_type(scalar)
    tiny = tiny_length(scalar)
    respond = respond_func(scalar)
    slide = slide_func(scalar)
    beyond_reach = beyond_reach_func(scalar)

    def body(x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool, radius: scalar, pose: transform,
             inv_pose: transform, inv_pose_prev: transform, grid: SdfGrid, brick_map: wp.array(dtype=wp.int32),
             values: wp.array(dtype=wp.float32), cells: wp.array(dtype=wp.uint8), depth_band: scalar,
             mu: scalar):
        if radius + depth_band >= scalar(grid.reach):
            return x, False, 4, 0
        q = wp.transform_point(inv_pose, x)
        state, d32, n32 = sdf_sample(grid, brick_map, values, cells, wp.vec3f(q))
        if state == EXACT:
            return x, False, 5, 1
        dist = scalar(d32)
        n = vec3(n32)
        q_old = wp.transform_point(inv_pose_prev, x_old)
        path = q - q_old
        length = wp.length(path)
        lead = wp.transform_point(inv_pose, leader)
        samples = int(0)  # WHY_EXACT's index of the field's answer: samples taken beyond the first
        taken = int(1)    # samples of the field taken (a diagnostic, COUNT_FIELD_TESTS)
        # the path could have reached the surface (a far end's distance is a lower bound)
        if length > tiny and dist - radius < length:
            s, ds, ns = sdf_sample(grid, brick_map, values, cells, wp.vec3f(q_old))
            samples = 1
            taken = int(2)
            if s == EXACT:
                return x, False, 6, taken
            if state == FAR and (not ccd or (s != FAR and scalar(ds) <= radius)):
                # beyond the band at the end, not traced (a round without the continuous test, or
                # a path from contact): which side it ended on is unknown, and the exact query
                # reaches its whole path below the surface
                return x, False, 7, taken
            if ccd:
                stop = radius * scalar(1.0e-3) + rest * scalar(1.0e-4)
                if scalar(ds) <= radius + stop and (state != ANSWERS or wp.dot(n, vec3(ns)) <= scalar(0.0)):
                    # from contact to where the field cannot say it stayed on the same side: the
                    # exact query decides
                    return x, False, 8, taken
                # traced only from outside the contact distance: a particle that starts in contact
                # and ends nearest a surface that looks the same way is left to the projection
                # (resting hair dips below the surface every substep, gravity alone g h^2, more than
                # a hair radius; stopping it where it crossed carried it along with a moving surface
                # whatever the friction)
                # the end's clearance: no point within it of the end is in contact (the distance is
                # 1-Lipschitz, the trace's own premise)
                end_clear = dist - radius - stop
                if wp.static(PATH_BOUNDS >= 1) and scalar(ds) > radius + stop and (scalar(ds) - radius - stop) + end_clear > length:
                    # every point of the path lies within one of its ends' clearances: no contact
                    return x, False, 3, taken
                if scalar(ds) > radius + stop:
                    direction = path / length
                    behind = -(scalar(2.0) * scalar(grid.tolerance) + stop)
                    t = scalar(0.0)
                    concluded = bool(False)
                    samples = 2
                    step = scalar(0.0)
                    last_gap = scalar(0.0)
                    relax = scalar(RELAXATION)
                    retreat = bool(False)
                    for _ in range(FIELD_TRACE_ITERATIONS):
                        gap = scalar(ds) - radius
                        if retreat or step > last_gap + gap:
                            # the relaxed step left the last sample's clearance and this one's apart, or
                            # landed behind the surface or in a cell the field cannot answer: back to
                            # the plain step from the last sample, unrelaxed from now on
                            t = t - step + last_gap
                            step = last_gap
                            relax = scalar(1.0)
                            s, ds, ns = sdf_sample(grid, brick_map, values, cells, wp.vec3f(q_old + t * direction))
                            taken += 1
                            if s == EXACT or scalar(ds) - radius < behind:
                                break
                            gap = scalar(ds) - radius
                        if gap <= stop:
                            # first contact: the particle stops on the contact plane there and goes
                            # back to the rest length on it (as the exact query's stop); friction: the
                            # path's end lay behind the plane by `blocked`
                            nc = vec3(ns)
                            stop_at = q_old + t * direction + (radius - scalar(ds)) * nc
                            if beyond_reach(lead, stop_at, nc, scalar(0.0), rest):
                                # the exact query decides (the face the segment enters the body
                                # through)
                                return x, False, 10, taken
                            blocked = wp.max(wp.dot(stop_at - q, nc), scalar(0.0))
                            y = slide(stop_at, q_old, lead, rest, nc, mu * blocked)
                            return wp.transform_point(pose, y), True, 2, taken
                        # the rest of the path within this sample's clearance and the end's: clear
                        if wp.static(PATH_BOUNDS >= 2) and (gap - stop) + end_clear > length - t:
                            concluded = True
                            break
                        if t + gap >= length:
                            concluded = True
                            break
                        step = wp.min(relax * gap, length - t)
                        last_gap = gap
                        t = t + step
                        s, ds, ns = sdf_sample(grid, brick_map, values, cells, wp.vec3f(q_old + t * direction))
                        taken += 1
                        retreat = s == EXACT or scalar(ds) - radius < behind
                        if retreat and relax == scalar(1.0):
                            break
                    if not concluded:
                        # a grazing path the trace could not follow to its end, or one found behind
                        # the surface without touching it: the exact ray decides
                        return x, False, 9, taken
        if dist >= radius:
            return x, False, samples, taken
        if beyond_reach(lead, q, n, radius - dist, rest):
            # (the particle round an edge from its leader's face): the exact query answers by the
            # face the segment from the leader enters the body through
            return x, False, 10, taken
        return wp.transform_point(pose, respond(q, q_old, lead, rest, dist, n, radius, mu)), True, samples, taken

    body.__name__ = body.__qualname__ = "collide_sdf_" + ("f64" if scalar == wp.float64 else "f32")
    return wp.func(body)


def sdf_fields() -> dict:
    """Struct fields of the mesh colliders' fields: per device collider its :class:`SdfGrid`
    (``cell`` 0: none), the brick maps, node distances and cell states of all of them, and the
    counts of their tests by outcome (``sdf_tests``, :data:`TEST_SLOTS` per entry of
    :data:`WHY_EXACT`; written only by kernels built with ``kernels.features.mesh.
    COUNT_FIELD_TESTS`` on, a diagnostic)."""
    return dict(collider_sdf=wp.array(dtype=SdfGrid), sdf_brick_map=wp.array(dtype=wp.int32),
                sdf_values=wp.array(dtype=wp.float32), sdf_cells=wp.array(dtype=wp.uint8),
                sdf_tests=wp.array(dtype=wp.int32))


# -- building the field (one collider, per frame) --------------------------------------------------


@wp.kernel(enable_backward=False)
def mark_bricks_kernel(mesh: wp.uint64, grid: SdfGrid, capacity: int, brick_map: wp.array(dtype=wp.int32),
                       brick_coords: wp.array(dtype=wp.vec3i), count: wp.array(dtype=wp.int32)):
    # Model: mesh (collider-local, m), grid (origin, cell, band, bricks, offsets), capacity (pool bricks)
    # Data in: -
    # Data out: brick_map[grid.map_offset + b] (slot, FAR_BRICK or OVERFLOW_BRICK), brick_coords of
    #   each slot, count[0] (bricks needed)
    b = wp.tid()
    nby = grid.bricks[1]
    nbz = grid.bricks[2]
    bz = b % nbz
    by = (b // nbz) % nby
    bx = b // (nbz * nby)
    centre = grid.origin + wp.vec3f(float(bx * 8 + 4), float(by * 8 + 4), float(bz * 8 + 4)) * grid.cell
    # a node of the brick within the band: its centre within band + the half diagonal (4 sqrt(3) cells)
    hit = wp.mesh_query_point_no_sign(mesh, centre, grid.band + BRICK_HALF_DIAGONAL * grid.cell)
    slot = int(FAR_BRICK)
    if hit.result:
        slot = wp.atomic_add(count, 0, 1)
        if slot < capacity:
            brick_coords[grid.pool_offset + slot] = wp.vec3i(bx, by, bz)
        else:
            slot = int(OVERFLOW_BRICK)
    brick_map[grid.map_offset + b] = slot


@wp.func
def node_distance(mesh: wp.uint64, grid: SdfGrid, p: wp.vec3f):
    """``(d, g)`` at node position ``p``: the signed distance (m; ``band`` beyond it) and the
    distance's unit gradient (outward; 0 beyond the band)."""
    query = wp.mesh_query_point_sign_normal(mesh, p, grid.band)
    d = grid.band
    g = wp.vec3f(0.0)
    if query.result:
        r = p - wp.mesh_eval_position(mesh, query.face, query.u, query.v)
        length = wp.length(r)
        s = wp.float32(1.0)
        if query.sign < 0.0:
            s = wp.float32(-1.0)
        d = s * length
        if length > wp.float32(1.0e-3) * grid.cell:  # else the direction is rounding noise
            g = r * (s / length)
        else:
            g = wp.mesh_eval_face_normal(mesh, query.face)
    return d, g


@wp.kernel(enable_backward=False)
def fill_nodes_kernel(mesh: wp.uint64, grid: SdfGrid, brick_coords: wp.array(dtype=wp.vec3i),
                      values: wp.array(dtype=wp.float32), gradients: wp.array(dtype=wp.vec3h)):
    # Model: mesh (collider-local, m), grid
    # Data in: brick_coords of the pool's used slots (launched over used slots x 512 own nodes:
    #   local 0..7 per axis; the last layer is the next brick's, see share_nodes_kernel)
    # Data out: values (signed distance, m; band beyond it), gradients (unit, outward; 0 beyond)
    t = wp.tid()
    slot = t // 512
    node = t - slot * 512
    i = node // 64
    j = (node // 8) % 8
    k = node % 8
    bc = brick_coords[grid.pool_offset + slot]
    p = grid.origin + wp.vec3f(float(bc[0] * 8 + i), float(bc[1] * 8 + j), float(bc[2] * 8 + k)) * grid.cell
    d, g = node_distance(mesh, grid, p)
    out = (grid.pool_offset + slot) * 729 + (i * 9 + j) * 9 + k
    values[out] = d
    gradients[out] = wp.vec3h(g)


@wp.kernel(enable_backward=False)
def share_nodes_kernel(mesh: wp.uint64, grid: SdfGrid, brick_map: wp.array(dtype=wp.int32),
                       brick_coords: wp.array(dtype=wp.vec3i), values: wp.array(dtype=wp.float32),
                       gradients: wp.array(dtype=wp.vec3h)):
    # Model: mesh, grid
    # Data in: brick_map, brick_coords, the own nodes of every used brick (fill_nodes_kernel)
    # Data out: values, gradients of the nodes on a brick's last layer (local 8 on some axis):
    #   copied from the neighbour brick that owns them; beyond the band where that brick is far
    #   (no node of it within the band); queried where it has no slot or lies outside the grid
    t = wp.tid()
    slot = t // 729
    node = t - slot * 729
    i = node // 81
    j = (node // 9) % 9
    k = node % 9
    if i < 8 and j < 8 and k < 8:
        return
    bc = brick_coords[grid.pool_offset + slot]
    nb = wp.vec3i(bc[0] + i // 8, bc[1] + j // 8, bc[2] + k // 8)
    out = (grid.pool_offset + slot) * 729 + node
    other = int(OVERFLOW_BRICK)
    if nb[0] < grid.bricks[0] and nb[1] < grid.bricks[1] and nb[2] < grid.bricks[2]:
        other = brick_map[grid.map_offset + (nb[0] * grid.bricks[1] + nb[1]) * grid.bricks[2] + nb[2]]
    if other >= 0:
        src = (grid.pool_offset + other) * 729 + ((i % 8) * 9 + (j % 8)) * 9 + (k % 8)
        values[out] = values[src]
        gradients[out] = gradients[src]
    elif other == FAR_BRICK:
        values[out] = grid.band
        gradients[out] = wp.vec3h(wp.vec3f(0.0))
    else:
        p = grid.origin + wp.vec3f(float(bc[0] * 8 + i), float(bc[1] * 8 + j), float(bc[2] * 8 + k)) * grid.cell
        d, g = node_distance(mesh, grid, p)
        values[out] = d
        gradients[out] = wp.vec3h(g)


@wp.func
def _edge_change(gradients: wp.array(dtype=wp.vec3h), b: int, step: int, axis: int):
    """The largest change of the gradient's ``axis`` component over the 4 cell edges along it."""
    worst = wp.float32(0.0)
    for e in range(4):
        # the 4 edges: base corner offsets 0 and the two other axes' steps
        o = int(0)
        if axis == 0:
            o = (e // 2) * 9 + (e % 2)
        elif axis == 1:
            o = (e // 2) * 81 + (e % 2)
        else:
            o = (e // 2) * 81 + (e % 2) * 9
        a = wp.float32(gradients[b + o][axis])
        c = wp.float32(gradients[b + o + step][axis])
        worst = wp.max(worst, wp.abs(c - a))
    return worst


@wp.kernel(enable_backward=False)
def cell_states_kernel(grid: SdfGrid, values: wp.array(dtype=wp.float32), gradients: wp.array(dtype=wp.vec3h),
                       cells: wp.array(dtype=wp.uint8)):
    # Model: grid (cell, band, tolerance, pool offset)
    # Data in: values, gradients of the used slots (launched over used slots x 512 cells)
    # Data out: cells (FAR, ANSWERS or EXACT; module docstring)
    t = wp.tid()
    slot = t // 512
    cell = t - slot * 512
    i = cell // 64
    j = (cell // 8) % 8
    k = cell % 8
    brick = grid.pool_offset + slot
    b = brick * 729 + (i * 9 + j) * 9 + k
    state = int(ANSWERS)
    for c in range(8):
        o = (c // 4) * 81 + ((c // 2) % 2) * 9 + (c % 2)
        if wp.abs(values[b + o]) >= grid.band:
            state = int(FAR)
    if state == ANSWERS:
        change = _edge_change(gradients, b, 81, 0) + _edge_change(gradients, b, 9, 1) + _edge_change(gradients, b, 1, 2)
        if wp.float32(0.125) * grid.cell * change > grid.tolerance:
            state = int(EXACT)
    cells[brick * 512 + cell] = wp.uint8(state)


# -- host-side probes (tests, benchmarks) -----------------------------------------------------------


@wp.kernel(enable_backward=False)
def sample_kernel(grids: wp.array(dtype=SdfGrid), c: int, brick_map: wp.array(dtype=wp.int32),
                  values: wp.array(dtype=wp.float32), cells: wp.array(dtype=wp.uint8),
                  points: wp.array(dtype=wp.vec3f), state: wp.array(dtype=wp.int32),
                  distance: wp.array(dtype=wp.float32), normal: wp.array(dtype=wp.vec3f)):
    # Model: the fields of device collider c
    # Data in: points (collider-local, m)
    # Data out: state (FAR, ANSWERS, EXACT), distance (m; FAR: a lower bound), normal (unit; ANSWERS)
    i = wp.tid()
    s, d, n = sdf_sample(grids[c], brick_map, values, cells, points[i])
    state[i] = s
    distance[i] = d
    normal[i] = n


@wp.kernel(enable_backward=False)
def mesh_distance_kernel(mesh: wp.uint64, points: wp.array(dtype=wp.vec3f), max_dist: wp.float32,
                         distance: wp.array(dtype=wp.float32), normal: wp.array(dtype=wp.vec3f)):
    # Model: mesh (local, m)
    # Data in: points (local, m), max_dist (m)
    # Data out: distance (signed, pseudo-normal sign; max_dist where nothing is closer), normal
    #   (unit gradient of the distance)
    i = wp.tid()
    p = points[i]
    query = wp.mesh_query_point_sign_normal(mesh, p, max_dist)
    distance[i] = max_dist
    normal[i] = wp.vec3f(0.0)
    if query.result:
        r = p - wp.mesh_eval_position(mesh, query.face, query.u, query.v)
        length = wp.length(r)
        s = wp.float32(1.0)
        if query.sign < 0.0:
            s = wp.float32(-1.0)
        distance[i] = s * length
        if length > 0.0:
            normal[i] = r * (s / length)
        else:
            normal[i] = wp.mesh_eval_face_normal(mesh, query.face)
