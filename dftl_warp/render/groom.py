"""Procedural grooms in numpy, for previews, benchmarks and tests (stage units: metres)."""

from __future__ import annotations

import numpy as np


def sphere_groom(strands=2000, vertices=16, radius=0.1, length=0.12, seed=0, droop=1.0, curl=0.004):
    """Strands rooted on the upper part of a sphere of ``radius`` at the origin (Y up), leaving
    at a shallow angle combed back and down along the scalp, bending down under a fake gravity ``droop`` with a little
    waviness ``curl``. Returns (points (strands*vertices, 3), counts)."""
    rng = np.random.default_rng(seed)
    # roots: uniform on the cap y > -0.2 r
    y = rng.uniform(-0.2, 1.0, strands)
    phi = rng.uniform(0.0, 2.0 * np.pi, strands)
    rxz = np.sqrt(1.0 - y * y)
    normal = np.stack([rxz * np.cos(phi), y, rxz * np.sin(phi)], axis=1)
    root = normal * radius * 1.001
    seg = length * rng.uniform(0.85, 1.15, strands)[:, None] / (vertices - 1)
    pts = np.empty((strands, vertices, 3))
    pts[:, 0] = root
    # roots leave at a shallow angle, combed along the scalp towards the back and down
    flow = np.array([0.0, -1.0, -0.35]) / np.linalg.norm([0.0, -1.0, -0.35])
    along = flow - (normal @ flow)[:, None] * normal
    along /= np.maximum(np.linalg.norm(along, axis=1, keepdims=True), 1e-9)
    direction = 0.45 * normal + along
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    down = np.array([0.0, -1.0, 0.0])
    wave_phase = rng.uniform(0, 2 * np.pi, strands)
    side = np.cross(normal, down)
    side /= np.maximum(np.linalg.norm(side, axis=1, keepdims=True), 1e-9)
    for i in range(1, vertices):
        direction = direction + droop * 0.22 * down
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        p = pts[:, i - 1] + direction * seg
        # keep the strand off the sphere
        d = np.linalg.norm(p, axis=1, keepdims=True)
        p = np.where(d < radius * 1.02, p / d * radius * 1.02, p)
        pts[:, i] = p
        wave = curl * np.sin(i * 0.9 + wave_phase)[:, None] * side
        pts[:, i] += wave * (i / vertices)
    return pts.reshape(-1, 3), np.full(strands, vertices)
