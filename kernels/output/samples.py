"""Output kernels: device state -> per-prim local-space samples in the caller's point order."""

import functools

import warp as wp


@functools.cache
def local_samples_kernel(scalar):
    """Kernel writing, for every input point ``j``, its position and velocity in its prim's local
    space, computed in float64 and stored in float32 (what USD stores):
    ``points = world_to_local(x + origin)``,
    ``velocities = linear(world_to_local)(v - frame_velocity(points))``.

    Matrices are column-vector 4x4 (the transposes of USD's row-vector matrices).
    ``frame_rate`` is d(local-to-world)/dt, the velocity a moving prim gives points fixed in it
    (zero for static prims): USD velocities are the rate of change of the local points.
    """
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def local_samples(
        point_slot: wp.array(dtype=wp.int32),
        point_member: wp.array(dtype=wp.int32),
        origin: wp.vec3d,
        world_to_local: wp.array(dtype=wp.mat44d),
        frame_rate: wp.array(dtype=wp.mat44d),
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        points_out: wp.array(dtype=wp.vec3f),
        velocities_out: wp.array(dtype=wp.vec3f),
    ):
        j = wp.tid()
        k = point_slot[j]
        m = point_member[j]
        x = positions[k]
        v = velocities[k]
        world = wp.vec3d(wp.float64(x[0]), wp.float64(x[1]), wp.float64(x[2])) + origin
        to_local = world_to_local[m]
        local = wp.transform_point(to_local, world)
        frame_velocity = wp.transform_point(frame_rate[m], local)
        velocity = wp.vec3d(wp.float64(v[0]), wp.float64(v[1]), wp.float64(v[2])) - frame_velocity
        local_velocity = wp.transform_vector(to_local, velocity)
        points_out[j] = wp.vec3f(wp.float32(local[0]), wp.float32(local[1]), wp.float32(local[2]))
        velocities_out[j] = wp.vec3f(wp.float32(local_velocity[0]), wp.float32(local_velocity[1]),
                                     wp.float32(local_velocity[2]))

    return local_samples
