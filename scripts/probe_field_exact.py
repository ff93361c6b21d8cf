#!/usr/bin/env python3
"""What the production scene's tests of the body's field that go to the exact mesh query "from
contact" are (``kernels/features/sdf.py``: WHY_EXACT 7 and 8): ``count_field_tests.py``'s counts
plus, for those tests, whether the path's ray hits the mesh (and which side), whether its end is
inside (exact query), the path's length in the field's reach, the start's sample, and how far the
particle is from its leader. The mesh collider's function is replaced by an instrumented copy
before any kernel is built (a diagnostic; the collisions themselves are unchanged).

    python scripts/probe_field_exact.py cuda:0 1000000 0 4      # device, strands, patch (0: none), frames
"""
import functools, sys
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np
import warp as wp
from dftl_warp.kernels.features import mesh as mk, sdf as sk
from dftl_warp.kernels.features.collide import named_func
import dftl_warp.features.colliders.sdf as host_sdf
EXTRA = ("7: no ray hit, end outside", "7: no ray hit, end inside", "7: ray hit", "7: other",
         "8: no ray hit, end outside", "8: no ray hit, end inside", "8: ray hit", "8: other",
         "7/8 len < reach", "7/8 len < 2 reach", "7/8 len >= 2 reach", "7/8 ds<=0", "7/8 end FAR", "7/8 ccd off",
         "len 2-4 reach", "len 4-8 reach", "len >= 8 reach", "hit front (sign>0)", "hit back", "path.n_start > 0 (leaving)",
         "end dist > 0 (exact, outside)", "|x_old - leader| > 1.5 rest")
BASE = len(sk.WHY_EXACT) + 1
host_sdf.WHY_EXACT = tuple(sk.WHY_EXACT) + ("samples",) + EXTRA
TS = sk.TEST_SLOTS

@functools.cache
def built(scalar, Features, count):
    vec3 = wp.types.vector(3, scalar)
    one = mk.collide_mesh_func(scalar)
    field = sk.collide_sdf_func(scalar)
    def collide_mesh_at(f: Features, c: int, x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool,
                        radius: scalar):
        grid = f.collider_sdf[c]
        if grid.cell > wp.float32(0.0):
            z, touched, why, taken = field(x, x_old, leader, rest, ccd, radius, f.collider_pose[c],
                                           f.collider_inv_pose[c], f.collider_inv_pose_prev[c], grid,
                                           f.sdf_brick_map, f.sdf_values, f.sdf_cells, f.collider_depth_band[c],
                                           f.collider_friction[c])
            slot = int(wp.abs(x[0] * scalar(7.3e4) + x[1] * scalar(3.1e4) + x[2] * scalar(1.7e4))) % TS
            wp.atomic_add(f.sdf_tests, why * TS + slot, 1)
            if why < sk.EXACT_FROM:
                return z, touched
            if why == 7 or why == 8:
                q = wp.transform_point(f.collider_inv_pose[c], x)
                q_old = wp.transform_point(f.collider_inv_pose_prev[c], x_old)
                path = q - q_old
                length = wp.length(path)
                base = BASE + 4 * (why - 7)
                mesh = f.collider_mesh[c]
                qp = wp.mesh_query_point_sign_normal(mesh, wp.vec3f(q), wp.float32(1.0))
                cat = 3
                if length > scalar(1e-9):
                    rh = wp.mesh_query_ray(mesh, wp.vec3f(q_old), wp.vec3f(path / length), wp.float32(length))
                    if rh.result:
                        cat = 2
                    elif qp.result:
                        if qp.sign > wp.float32(0.0):
                            cat = 0
                        else:
                            cat = 1
                wp.atomic_add(f.sdf_tests, (base + cat) * TS + slot, 1)
                reach = scalar(grid.reach)
                lc = 2
                if length < reach:
                    lc = 0
                elif length < scalar(2.0) * reach:
                    lc = 1
                wp.atomic_add(f.sdf_tests, (BASE + 8 + lc) * TS + slot, 1)
                st0, d0, n0 = sk.sdf_sample(grid, f.sdf_brick_map, f.sdf_values, f.sdf_cells, wp.vec3f(q_old))
                if d0 <= wp.float32(0.0):
                    wp.atomic_add(f.sdf_tests, (BASE + 11) * TS + slot, 1)
                st1, d1, n1 = sk.sdf_sample(grid, f.sdf_brick_map, f.sdf_values, f.sdf_cells, wp.vec3f(q))
                if st1 == sk.FAR:
                    wp.atomic_add(f.sdf_tests, (BASE + 12) * TS + slot, 1)
                if not ccd:
                    wp.atomic_add(f.sdf_tests, (BASE + 13) * TS + slot, 1)
                r = length / reach
                if r >= scalar(2.0):
                    lb = 14
                    if r >= scalar(8.0):
                        lb = 16
                    elif r >= scalar(4.0):
                        lb = 15
                    wp.atomic_add(f.sdf_tests, (BASE + lb) * TS + slot, 1)
                if length > scalar(1e-9):
                    rh2 = wp.mesh_query_ray(mesh, wp.vec3f(q_old), wp.vec3f(path / length), wp.float32(length))
                    if rh2.result:
                        if rh2.sign > wp.float32(0.0):
                            wp.atomic_add(f.sdf_tests, (BASE + 17) * TS + slot, 1)
                        else:
                            wp.atomic_add(f.sdf_tests, (BASE + 18) * TS + slot, 1)
                    if wp.dot(vec3(n0), path) > scalar(0.0):
                        wp.atomic_add(f.sdf_tests, (BASE + 19) * TS + slot, 1)
                if qp.result and qp.sign > wp.float32(0.0):
                    wp.atomic_add(f.sdf_tests, (BASE + 20) * TS + slot, 1)
                if wp.length(x_old - leader) > scalar(1.5) * rest:
                    wp.atomic_add(f.sdf_tests, (BASE + 21) * TS + slot, 1)
        y, hit = one(x, x_old, leader, rest, ccd, radius, f.collider_pose[c], f.collider_inv_pose[c],
                     f.collider_inv_pose_prev[c], f.collider_mesh[c], f.collider_mesh_prev[c],
                         f.collider_motion[c], f.collider_lower[c], f.collider_upper[c],
                     f.collider_depth_band[c], f.collider_friction[c])
        return y, hit
    return named_func(collide_mesh_at, "collide_mesh_at_probe", unique=True)

mk._collide_mesh_at_built = built
import count_field_tests as cft
dev, strands, patch_n, frames = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
args = ["--device", dev, "--strands", strands, "--frames", frames, "--only", "production scene:"]
if int(patch_n):
    args += ["--patch", patch_n]
cft.main(args)
