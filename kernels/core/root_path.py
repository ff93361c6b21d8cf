"""The root's path inside a frame: the only place a kernel learns where a kinematic root is.

Across a frame of duration ``T`` (s) a root moves from ``start`` to ``end`` (m) on the cubic
Hermite curve whose velocities at the frame's ends are ``v0`` and ``v1`` (m/s). With
``alpha = t / T`` in [0, 1], ``chord = end - start`` and the tangents' deviations from the chord
``d0 = T v0 - chord``, ``d1 = T v1 - chord`` (m, per strand, :class:`~dftl_warp.core.state.Control`):

    x(alpha) = start + alpha chord + alpha (1 - alpha) ((1 - alpha) d0 - alpha d1)

which is the Hermite form ``h00 start + h10 T v0 + h01 end + h11 T v1`` rewritten (``h10 + h11 +
h01 = alpha``): its position is ``start`` / ``end`` at alpha 0 / 1 and its velocity
``dx/dt = (chord + (1 - alpha)(1 - 3 alpha) d0 - alpha (2 - 3 alpha) d1) / T`` is ``v0`` / ``v1``,
so a root whose frames share their end velocities moves with a continuous velocity (C1). With
zero deviations (the default, or tangents ``T v = chord``) the correction term is exactly zero and
the path is the linear one, ``start + alpha chord``, bit for bit.
"""

import functools
from typing import Any

import warp as wp


@wp.func
def root_on_path(start: Any, chord: Any, deviation_start: Any, deviation_end: Any, alpha: Any):
    """Root position at ``alpha`` in [0, 1] of the frame: ``start`` + ``alpha chord`` + the Hermite
    correction of the tangents' deviations from the chord (all m; see the module docstring)."""
    beta = type(alpha)(1.0) - alpha
    return start + alpha * chord + (alpha * beta) * (beta * deviation_start - alpha * deviation_end)


@functools.cache
def path_deviation_kernel(scalar):
    """Kernel: per strand, the tangents' deviations ``d = T v - (end - start)`` (m) from root
    targets and root velocities already on the device (bound roots), ``T`` the frame's duration (s)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def path_deviations(
        # Data in: root targets (m) and root velocities (m/s) at the frame's start and end
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
        velocity_start: wp.array(dtype=vec3),
        velocity_end: wp.array(dtype=vec3),
        frame_duration: scalar,
        # Data out:
        deviation_start: wp.array(dtype=vec3),
        deviation_end: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        chord = root_end[s] - root_start[s]
        deviation_start[s] = frame_duration * velocity_start[s] - chord
        deviation_end[s] = frame_duration * velocity_end[s] - chord

    return path_deviations
