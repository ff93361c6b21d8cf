"""Root targets (and the elastic solver's clamp ghosts) of prims whose roots move with their
transforms, computed on the device from the prims' matrices (``dftl_warp/simulation/transform_roots.py``).

A root fixed at ``x`` in its prim's local space is ``x M`` in the world (``M`` the prim's 4x4
row-vector local-to-world matrix, as :func:`dftl_warp.usd.scene.transform_points`); its velocity is
``x R`` with ``R`` the matrix's rate (the same finite difference of the frames' matrices that the
host applied to the frames' points before: the roots are linear in the matrix). Per device strand
the kernel writes what ``Control.set_root_targets`` writes from host arrays: the targets at the
frame's start and end relative to the model origin, in the model's precision, and the Hermite
tangents' deviations from the chord ``T v - (end - start)``, the chord taken between the rounded
targets. Arithmetic in float64, as on the host.
"""

import functools

import warp as wp


@wp.func
def through(m: wp.mat44d, x: wp.vec3d):
    """``x`` (row vector) through the affine row-vector matrix ``m``."""
    return wp.vec3d(x[0] * m[0, 0] + x[1] * m[1, 0] + x[2] * m[2, 0] + m[3, 0],
                    x[0] * m[0, 1] + x[1] * m[1, 1] + x[2] * m[2, 1] + m[3, 1],
                    x[0] * m[0, 2] + x[1] * m[1, 2] + x[2] * m[2, 2] + m[3, 2])


@functools.cache
def transform_roots_kernel(scalar):
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def transform_roots(
        # Model: per device strand, its prim (index into the matrices) and its point in the prim's space
        prim: wp.array(dtype=wp.int32),
        local: wp.array(dtype=wp.vec3d),
        origin: wp.vec3d,
        # Frame in: per prim, the matrices at the frame's start and end and their rates (1/s)
        matrix_start: wp.array(dtype=wp.mat44d),
        matrix_end: wp.array(dtype=wp.mat44d),
        rate_start: wp.array(dtype=wp.mat44d),
        rate_end: wp.array(dtype=wp.mat44d),
        frame_duration: wp.float64,
        # Data out: targets relative to the origin, and the tangents' deviations from the chord
        start: wp.array(dtype=vec3),
        end: wp.array(dtype=vec3),
        deviation_start: wp.array(dtype=vec3),
        deviation_end: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        p = prim[s]
        x = local[s]
        a = vec3(through(matrix_start[p], x) - origin)
        b = vec3(through(matrix_end[p], x) - origin)
        start[s] = a
        end[s] = b
        chord = wp.vec3d(b) - wp.vec3d(a)
        deviation_start[s] = vec3(frame_duration * through(rate_start[p], x) - chord)
        deviation_end[s] = vec3(frame_duration * through(rate_end[p], x) - chord)

    return transform_roots


@functools.cache
def gather_rotations_kernel(scalar):
    mat33 = wp.types.matrix((3, 3), scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def gather_rotations(
        # Model: per device strand, its prim
        prim: wp.array(dtype=wp.int32),
        # Frame in: per prim, the rotations (column vectors) at the frame's start and end
        rotation_start: wp.array(dtype=wp.mat33d),
        rotation_end: wp.array(dtype=wp.mat33d),
        # Data out: per device strand
        start: wp.array(dtype=mat33),
        end: wp.array(dtype=mat33),
    ):
        s = wp.tid()
        start[s] = mat33(rotation_start[prim[s]])
        end[s] = mat33(rotation_end[prim[s]])

    return gather_rotations
