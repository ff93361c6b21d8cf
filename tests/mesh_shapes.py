"""Closed test meshes shared by the collider tests."""

from __future__ import annotations

import numpy as np


def uv_sphere(rings: int, segments: int):
    """Unit UV sphere: points (P, 3) (its unit directions) and outward triangles (T, 3)."""
    theta = np.linspace(0, np.pi, rings + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring_pts = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    pts = np.concatenate([[[0, 1, 0]], ring_pts, [[0, -1, 0]]])
    ring = lambda r, s: 1 + r * segments + s % segments  # noqa: E731
    last = len(pts) - 1
    tris = []
    for s in range(segments):
        tris += [(0, ring(0, s + 1), ring(0, s)), (last, ring(rings - 2, s), ring(rings - 2, s + 1))]
        for r in range(rings - 2):
            a, b, c, d = ring(r, s), ring(r, s + 1), ring(r + 1, s), ring(r + 1, s + 1)
            tris += [(a, b, d), (a, d, c)]
    tris = np.array(tris)
    tri = pts[tris]
    flip = np.sum(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * tri.mean(1), axis=1) < 0
    tris[flip] = tris[flip][:, ::-1]
    return pts, tris
