"""Ray-traced hair preview: camera rays, strand tubes through a BVH, gprims, hair shading.

Everything is float32 and relative to the render's world ``origin`` (the host subtracts it), so
a groom far from (0, 0, 0) keeps its precision. Lengths are in stage units (metres for the
simulator's output).

- Strands are *round linear curves*: each segment is the sweep of a sphere whose radius varies
  linearly from ``r0`` at ``p0`` to ``r1`` at ``p1`` (a cone with spherical joints, as Embree's
  and Mitsuba's ``linearcurve``). :func:`segment_bounds` writes the segment boxes of a
  ``wp.Bvh``; a new frame rewrites them and refits the tree.
- Other geometry: analytic spheres, capsules and boxes (each in its own local frame) and one
  triangle ``wp.Mesh``.
- Shading (:func:`.shading.hair_marschner`, in :mod:`.shading`): the R, TT and TRT lobes of Marschner et al. 2003 in the
  practical form of Karis 2016 ("Physically Based Hair Shading in Unreal"), plus a diffuse
  term for multiple scattering; or Kajiya-Kay 1989. A key light casts ray-traced shadows in
  which every hair crossed keeps ``hair_shadow_transmittance`` of the light, a fill light does
  not; an ambient term lifts the shadows.
- Thin strands: :func:`widen_radii` widens every tube to a minimum width in pixels at its
  camera depth, and the camera rays see it with the opacity true / drawn radius
  (:func:`hair_opacity`), composited front to back by :mod:`.pixel`.
- :func:`.pixel.render_kernel` (in :mod:`.pixel`): one thread per pixel.
"""

import warp as wp

HIT_NONE = wp.constant(-1)
HIT_HAIR = wp.constant(0)
HIT_SHAPE = wp.constant(1)
HIT_MESH = wp.constant(2)

SHAPE_SPHERE = wp.constant(0)
SHAPE_CAPSULE = wp.constant(1)
SHAPE_BOX = wp.constant(2)

BIG = wp.constant(1.0e30)


@wp.struct
class RenderCamera:
    """A pinhole (or orthographic) camera in render space.

    ``world_from_camera`` maps camera space (looking down -z, +y up) to render space.
    ``window`` = (left, right, bottom, top) of the image on the plane z = -1 (perspective) or
    z = 0 in stage units (orthographic), already conformed to the image aspect. ``near``/``far``
    are clipping distances along -z.
    """

    world_from_camera: wp.mat44
    window: wp.vec4
    near: float
    far: float
    orthographic: int
    width: int
    height: int


@wp.struct
class RenderLights:
    """Directional lights (unit vectors towards the light), colours are linear radiance."""

    key_dir: wp.vec3
    key_color: wp.vec3
    fill_dir: wp.vec3
    fill_color: wp.vec3
    ambient: wp.vec3
    hair_shadow_transmittance: float
    shading: int
    roughness: float
    geometry_albedo: wp.vec3


@wp.struct
class RenderHair:
    """Strand segments: ``seg_v0[i]`` is the first of the two vertices of segment ``i``.

    ``radii`` are the strands' true radii, ``drawn`` the radii the camera rays intersect (the true
    ones widened to the minimum pixel width, :func:`widen_radii`); a drawn tube is seen with the
    opacity true / drawn radius (:func:`hair_opacity`). Shadow rays cross the true tubes.
    """

    bvh: wp.uint64
    count: int
    seg_v0: wp.array(dtype=wp.int32)
    seg_strand: wp.array(dtype=wp.int32)
    points: wp.array(dtype=wp.vec3)
    radii: wp.array(dtype=float)
    drawn: wp.array(dtype=float)
    colors: wp.array(dtype=wp.vec3)


@wp.struct
class RenderShapes:
    """Analytic gprims: ``local_from_world`` per shape, params (see :func:`shape_hit`)."""

    count: int
    kind: wp.array(dtype=wp.int32)
    local_from_world: wp.array(dtype=wp.mat44)
    params: wp.array(dtype=wp.vec3)
    mesh: wp.uint64
    has_mesh: int


@wp.kernel(enable_backward=False, module="unique")
def widen_radii(
    camera_from_world: wp.mat44,
    orthographic: int,
    reach: float,
    radii: wp.array(dtype=float),
    points: wp.array(dtype=wp.vec3),
    drawn: wp.array(dtype=float),
):
    """Drawn radius of every vertex: its true radius, or ``reach`` x its camera depth (perspective;
    ``reach`` alone when orthographic) where that is larger. ``reach`` is half the minimum pixel
    width times the world size of a pixel at camera depth 1 (orthographic: at any depth). A vertex
    of radius 0, or behind a perspective camera, is not widened."""
    i = wp.tid()
    r = radii[i]
    half = reach
    if orthographic == 0:
        depth = -wp.transform_point(camera_from_world, points[i])[2]
        half = reach * wp.max(depth, 0.0)
    if r > 0.0 and half > r:
        drawn[i] = half
    else:
        drawn[i] = r


@wp.kernel(enable_backward=False, module="unique")
def segment_bounds(
    seg_v0: wp.array(dtype=wp.int32),
    points: wp.array(dtype=wp.vec3),
    radii: wp.array(dtype=float),
    lowers: wp.array(dtype=wp.vec3),
    uppers: wp.array(dtype=wp.vec3),
):
    """Axis-aligned box of every segment tube (the BVH items)."""
    i = wp.tid()
    v = seg_v0[i]
    a = points[v]
    b = points[v + 1]
    r = wp.max(radii[v], radii[v + 1])
    pad = wp.vec3(r, r, r)
    lowers[i] = wp.min(a, b) - pad
    uppers[i] = wp.max(a, b) + pad


@wp.func
def round_cone_hit(ro: wp.vec3, rd: wp.vec3, pa: wp.vec3, pb: wp.vec3, ra: float, rb: float):
    """Entry distance of the unit ray ``ro + t rd`` into the sphere-swept cone from (pa, ra) to
    (pb, rb), or ``BIG`` if it misses or starts inside (after I. Quilez, "rounded cone").

    The ray origin is first moved next to the segment so that the quadratic does not lose the
    tube's (tiny) radius to cancellation in float32.
    """
    t_shift = wp.dot(pa - ro, rd)
    o = ro + t_shift * rd
    ba = pb - pa
    oa = o - pa
    ob = o - pb
    rr = ra - rb
    m0 = wp.dot(ba, ba)
    m1 = wp.dot(ba, oa)
    m2 = wp.dot(ba, rd)
    m3 = wp.dot(rd, oa)
    m5 = wp.dot(oa, oa)
    m6 = wp.dot(ob, rd)
    m7 = wp.dot(ob, ob)
    d2 = m0 - rr * rr
    result = BIG
    if d2 > 0.0:
        # the conical body
        k2 = d2 - m2 * m2
        k1 = d2 * m3 - m1 * m2 + m2 * rr * ra
        k0 = d2 * m5 - m1 * m1 + m1 * rr * ra * 2.0 - m0 * ra * ra
        h = k1 * k1 - k0 * k2
        if h >= 0.0 and k2 > 0.0:
            t = (-wp.sqrt(h) - k1) / k2
            y = m1 - ra * rr + t * m2
            if y > 0.0 and y < d2:
                return t + t_shift
    # the two spheres at the ends
    h1 = m3 * m3 - m5 + ra * ra
    if h1 > 0.0:
        result = -m3 - wp.sqrt(h1)
    h2 = m6 * m6 - m7 + rb * rb
    if h2 > 0.0:
        t = -m6 - wp.sqrt(h2)
        if t < result:
            result = t
    if result < BIG:
        return result + t_shift
    return BIG


@wp.func
def sphere_hit(o: wp.vec3, d: wp.vec3, r: float):
    """Entry parameter of ``o + t d`` into the sphere of radius ``r`` at 0 (BIG if none)."""
    a = wp.dot(d, d)
    b = wp.dot(o, d)
    c = wp.dot(o, o) - r * r
    h = b * b - a * c
    if h < 0.0:
        return BIG
    t = (-b - wp.sqrt(h)) / a
    if t < 0.0:
        return BIG
    return t


@wp.func
def box_hit(o: wp.vec3, d: wp.vec3, half: wp.vec3):
    """Entry parameter of ``o + t d`` into the box ``[-half, half]`` (BIG if none)."""
    t0 = float(-BIG)
    t1 = float(BIG)
    for k in range(3):
        if wp.abs(d[k]) < 1.0e-20:
            if o[k] < -half[k] or o[k] > half[k]:
                return BIG
        else:
            ta = (-half[k] - o[k]) / d[k]
            tb = (half[k] - o[k]) / d[k]
            t0 = wp.max(t0, wp.min(ta, tb))
            t1 = wp.min(t1, wp.max(ta, tb))
    if t0 > t1 or t0 < 0.0:
        return BIG
    return t0


@wp.func
def capsule_axis(axis: float):
    if axis < 0.5:
        return wp.vec3(1.0, 0.0, 0.0)
    if axis < 1.5:
        return wp.vec3(0.0, 1.0, 0.0)
    return wp.vec3(0.0, 0.0, 1.0)


@wp.func
def shape_hit(kind: int, m: wp.mat44, params: wp.vec3, ro: wp.vec3, rd: wp.vec3):
    """Hit parameter (distance along the unit world ray) of one gprim, or BIG.

    params: sphere (radius, -, -); capsule (radius, half height of the cylinder, axis 0/1/2);
    box (half extents).
    """
    o = wp.transform_point(m, ro)
    d = wp.transform_vector(m, rd)
    if kind == SHAPE_SPHERE:
        return sphere_hit(o, d, params[0])
    if kind == SHAPE_CAPSULE:
        ax = capsule_axis(params[2]) * params[1]
        # the round-cone test wants a unit ray: scale t back
        dl = wp.length(d)
        t = round_cone_hit(o, d / dl, -ax, ax, params[0], params[0])
        if t < BIG and t > 0.0:
            return t / dl
        return BIG
    return box_hit(o, d, params)


@wp.func
def shape_normal(kind: int, m: wp.mat44, params: wp.vec3, p: wp.vec3):
    """World normal of a gprim at the world point ``p``."""
    q = wp.transform_point(m, p)
    n = q
    if kind == SHAPE_CAPSULE:
        ax = capsule_axis(params[2])
        s = wp.clamp(wp.dot(q, ax), -params[1], params[1])
        n = q - s * ax
    if kind == SHAPE_BOX:
        a = wp.vec3(wp.abs(q[0]) / params[0], wp.abs(q[1]) / params[1], wp.abs(q[2]) / params[2])
        if a[0] >= a[1] and a[0] >= a[2]:
            n = wp.vec3(wp.sign(q[0]), 0.0, 0.0)
        elif a[1] >= a[2]:
            n = wp.vec3(0.0, wp.sign(q[1]), 0.0)
        else:
            n = wp.vec3(0.0, 0.0, wp.sign(q[2]))
    # normals transform with the transpose of local_from_world
    nw = wp.vec3(
        m[0, 0] * n[0] + m[1, 0] * n[1] + m[2, 0] * n[2],
        m[0, 1] * n[0] + m[1, 1] * n[1] + m[2, 1] * n[2],
        m[0, 2] * n[0] + m[1, 2] * n[1] + m[2, 2] * n[2],
    )
    return wp.normalize(nw)


@wp.func
def segment_param(hair: RenderHair, v: int, p: wp.vec3):
    """Parameter (0 at vertex ``v``, 1 at ``v + 1``) of the point of the segment axis nearest ``p``."""
    a = hair.points[v]
    ab = hair.points[v + 1] - a
    len2 = wp.dot(ab, ab)
    if len2 > 0.0:
        return wp.clamp(wp.dot(p - a, ab) / len2, 0.0, 1.0)
    return 0.0


@wp.func
def hair_opacity(hair: RenderHair, v: int, u: float):
    """Opacity of the drawn tube of the segment from vertex ``v`` at parameter ``u``: true radius /
    drawn radius, exactly 1 where neither end is widened (the strand covers what it covers)."""
    r0 = hair.radii[v]
    r1 = hair.radii[v + 1]
    d0 = hair.drawn[v]
    d1 = hair.drawn[v + 1]
    if d0 == r0 and d1 == r1:
        return 1.0
    d = d0 + (d1 - d0) * u
    if d <= 0.0:
        return 1.0
    return wp.min((r0 + (r1 - r0) * u) / d, 1.0)


@wp.func
def hair_closest(hair: RenderHair, ro: wp.vec3, rd: wp.vec3, t_min: float, t_max: float, skip_segment: int,
                 key: int):
    """Closest drawn strand segment hit in (t_min, t_max): returns (t, segment) or (t_max, -1).

    The segment ``skip_segment`` and its neighbours on the same strand are not counted (the last
    layer composited: their joints overlap). ``key`` >= 0: stochastic transparency, a hit counts
    with probability its opacity, one draw per strand and key."""
    best_t = t_max
    best = int(-1)
    if hair.count > 0:
        skip_strand = int(-1)
        if skip_segment >= 0:
            skip_strand = hair.seg_strand[skip_segment]
        query = wp.bvh_query_ray(hair.bvh, ro, rd)
        i = int(0)
        while wp.bvh_query_next(query, i, best_t):
            if hair.seg_strand[i] == skip_strand and wp.abs(i - skip_segment) <= 1:
                continue
            v = hair.seg_v0[i]
            t = round_cone_hit(ro, rd, hair.points[v], hair.points[v + 1], hair.drawn[v], hair.drawn[v + 1])
            if t > t_min and t < best_t:
                if key >= 0:
                    a = hair_opacity(hair, v, segment_param(hair, v, ro + t * rd))
                    if a < 1.0:
                        draw = wp.rand_init(key, hair.seg_strand[i])
                        if wp.randf(draw) >= a:
                            continue
                best_t = t
                best = i
    return best_t, best


@wp.func
def hair_transmittance(hair: RenderHair, ro: wp.vec3, rd: wp.vec3, skip_segment: int, per_hair: float):
    """Light left after the strands crossed by the shadow ray ``ro + t rd`` (t > 0).

    The segment ``skip_segment`` and its neighbours on the same strand are not counted (the
    ray leaves from their surface).
    """
    tr = float(1.0)
    if hair.count > 0:
        skip_strand = int(-1)
        if skip_segment >= 0:
            skip_strand = hair.seg_strand[skip_segment]
        query = wp.bvh_query_ray(hair.bvh, ro, rd)
        i = int(0)
        while wp.bvh_query_next(query, i):
            if hair.seg_strand[i] == skip_strand and wp.abs(i - skip_segment) <= 1:
                continue
            v = hair.seg_v0[i]
            t = round_cone_hit(ro, rd, hair.points[v], hair.points[v + 1], hair.radii[v], hair.radii[v + 1])
            if t > 0.0 and t < BIG:
                tr = tr * per_hair
                if tr < 0.01:
                    return 0.0
    return tr


@wp.func
def geometry_closest(shapes: RenderShapes, ro: wp.vec3, rd: wp.vec3, t_min: float, t_max: float):
    """Closest gprim or mesh hit: returns (t, kind HIT_*, index, world normal)."""
    best_t = t_max
    kind = int(HIT_NONE)
    index = int(-1)
    normal = wp.vec3(0.0, 0.0, 1.0)
    for s in range(shapes.count):
        t = shape_hit(shapes.kind[s], shapes.local_from_world[s], shapes.params[s], ro, rd)
        if t > t_min and t < best_t:
            best_t = t
            kind = HIT_SHAPE
            index = s
    if kind == HIT_SHAPE:
        normal = shape_normal(
            shapes.kind[index], shapes.local_from_world[index], shapes.params[index], ro + best_t * rd
        )
    if shapes.has_mesh != 0:
        q = wp.mesh_query_ray(shapes.mesh, ro, rd, best_t)
        if q.result and q.t > t_min and q.t < best_t:
            best_t = q.t
            kind = HIT_MESH
            index = q.face
            normal = wp.normalize(q.normal)
    return best_t, kind, index, normal


@wp.func
def geometry_blocks(shapes: RenderShapes, ro: wp.vec3, rd: wp.vec3):
    """True if a gprim or mesh lies on the shadow ray ``ro + t rd`` (t > 0)."""
    for s in range(shapes.count):
        t = shape_hit(shapes.kind[s], shapes.local_from_world[s], shapes.params[s], ro, rd)
        if t > 0.0 and t < BIG:
            return True
    if shapes.has_mesh != 0:
        q = wp.mesh_query_ray(shapes.mesh, ro, rd, BIG)
        if q.result and q.t > 0.0:
            return True
    return False


@wp.func
def camera_ray(cam: RenderCamera, x: float, y: float):
    """Origin, unit direction and (near, far) distances of the ray through image position
    (x, y) in pixels (0..width, 0..height from the top-left corner)."""
    w = cam.window
    sx = w[0] + (w[1] - w[0]) * (x / float(cam.width))
    sy = w[3] - (w[3] - w[2]) * (y / float(cam.height))
    origin_c = wp.vec3(0.0, 0.0, 0.0)
    dir_c = wp.vec3(sx, sy, -1.0)
    if cam.orthographic != 0:
        origin_c = wp.vec3(sx, sy, 0.0)
        dir_c = wp.vec3(0.0, 0.0, -1.0)
    ro = wp.transform_point(cam.world_from_camera, origin_c)
    dv = wp.transform_vector(cam.world_from_camera, dir_c)
    scale = wp.length(dv)  # world distance per unit of camera depth
    rd = dv / scale
    return ro, rd, cam.near * scale, cam.far * scale
