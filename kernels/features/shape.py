"""Shape retention: a rest-shape target for each particle in its strand's local frame.

Frames are carried along each strand by parallel transport (the minimal rotation taking one
segment's direction to the next), both on the rest shape (on the host, to store each segment's
rest direction in the frame of the segment before it) and during the sweep. The first segment's
frame is the minimal rotation from the rest first direction to the current one applied to the
rest frame, so the targets are always a rigid motion of the rest shape, and the shape term is
relative: it holds curls and styling but not a global pose.
"""


import functools

import warp as wp


@functools.cache
def shape_funcs(scalar):
    """``(quat_between, advance_frame)`` for ``scalar`` precision.

    ``quat_between(a, b)``: the minimal rotation taking unit ``a`` to unit ``b``;
    ``advance_frame(frame, t_prev, t)``: the frame transported from direction ``t_prev`` to ``t``.
    """
    vec3 = wp.types.vector(3, scalar)
    quat = wp.types.quaternion(dtype=scalar)
    one = scalar(1.0)
    zero = scalar(0.0)

    @wp.func
    def quat_between(a: vec3, b: vec3):
        c = wp.dot(a, b)
        if c < scalar(-0.999999):
            # opposite: a half turn about any axis perpendicular to a
            axis = wp.cross(a, vec3(one, zero, zero))
            if wp.length(axis) < scalar(1.0e-3):
                axis = wp.cross(a, vec3(zero, one, zero))
            axis = wp.normalize(axis)
            return quat(axis[0], axis[1], axis[2], zero)
        v = wp.cross(a, b)
        return wp.normalize(quat(v[0], v[1], v[2], one + c))

    @wp.func
    def advance_frame(frame: quat, t_prev: vec3, t: vec3):
        return wp.normalize(quat_between(t_prev, t) * frame)

    return quat_between, advance_frame
