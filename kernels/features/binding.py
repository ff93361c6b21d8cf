"""Roots bound to a deforming triangle mesh: each root is a barycentric point on one triangle."""


import functools

import warp as wp


@functools.cache
def bind_roots_kernel(scalar):
    """Kernel: root targets of each device strand from the mesh points at frame start and end.

    ``root = w0 p[i0] + w1 p[i1] + w2 p[i2]`` with the strand's triangle ``(i0, i1, i2)`` and
    barycentric weights ``w``; points and roots in device coordinates (m). The sums are linear,
    so the same kernel gives the roots' velocities (m/s) from the points' velocities."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def bind_roots(
        triangle: wp.array(dtype=wp.vec3i),
        weights: wp.array(dtype=vec3),
        points_start: wp.array(dtype=vec3),
        points_end: wp.array(dtype=vec3),
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        t = triangle[s]
        w = weights[s]
        root_start[s] = w[0] * points_start[t[0]] + w[1] * points_start[t[1]] + w[2] * points_start[t[2]]
        root_end[s] = w[0] * points_end[t[0]] + w[1] * points_end[t[1]] + w[2] * points_end[t[2]]

    return bind_roots


@wp.kernel(enable_backward=False, module="unique")
def closest_face(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), face: wp.array(dtype=wp.int32),
                 bary: wp.array(dtype=wp.vec3)):
    """Closest triangle of ``mesh`` to each point, with the barycentric weights of the closest point."""
    i = wp.tid()
    q = wp.mesh_query_point_no_sign(mesh, points[i], 1.0e30)
    if q.result:
        face[i] = q.face
        bary[i] = wp.vec3(q.u, q.v, 1.0 - q.u - q.v)
    else:
        face[i] = -1
