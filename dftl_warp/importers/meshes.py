"""Head meshes for ``dftl-warp import --head``: Wavefront OBJ (``v`` and ``f`` lines; ``v/vt/vn``
and negative indices; every object and group merged) and PLY (``vertex`` x y z and ``face`` with a
``vertex_indices`` or ``vertex_index`` list). Returns points (N, 3), faceVertexCounts and
faceVertexIndices as USD wants them."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ._binary import read_bytes


@dataclass
class MeshData:
    points: np.ndarray
    face_counts: np.ndarray
    face_indices: np.ndarray


def read_obj(data: bytes, path: str) -> MeshData:
    text = data.decode("utf-8", errors="replace")
    points, counts, indices = [], [], []
    for no, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if not words:
            continue
        if words[0] == "v":
            try:
                points.append([float(w) for w in words[1:4]])
            except ValueError:
                points = None
            if points is None or len(points[-1]) != 3:
                raise UserError(f"{path}: line {no}: bad vertex {line.strip()[:60]!r}")
        elif words[0] == "f":
            face = []
            for w in words[1:]:
                try:
                    i = int(w.split("/")[0])
                except ValueError:
                    raise UserError(f"{path}: line {no}: bad face index {w!r}") from None
                i = i - 1 if i > 0 else len(points) + i  # OBJ indices are 1-based; negative ones are relative
                if i < 0 or i >= len(points) or w.split("/")[0] == "0":
                    raise UserError(f"{path}: line {no}: face index {w!r} is out of range (1..{len(points)})")
                face.append(i)
            if len(face) < 3:
                raise UserError(f"{path}: line {no}: a face needs at least 3 vertices")
            counts.append(len(face))
            indices.extend(face)
    return _mesh(path, np.array(points, dtype=np.float64).reshape(-1, 3), counts, indices)


def read_ply_mesh(data: bytes, path: str) -> MeshData:
    from .ply import read_ply, vertex_positions

    elements = read_ply(data, path)
    points = vertex_positions(elements, path)
    face = elements.get("face")
    if face is None:
        raise UserError(f"{path}: no 'face' element: not a mesh")
    lists = face.data.get("vertex_indices", face.data.get("vertex_index"))
    if not isinstance(lists, list):
        raise UserError(f"{path}: element 'face' has no 'vertex_indices' list")
    counts = [len(f) for f in lists]
    bad = [k for k, c in enumerate(counts) if c < 3]
    if bad:
        raise UserError(f"{path}: face {bad[0]}: a face needs at least 3 vertices")
    indices = np.concatenate([np.asarray(f, dtype=np.int64) for f in lists]) if lists else np.zeros(0, np.int64)
    out = np.flatnonzero((indices < 0) | (indices >= points.shape[0]))
    if out.size:
        raise UserError(f"{path}: face vertex index {int(indices[out[0]])} is out of range (0..{points.shape[0] - 1})")
    return _mesh(path, points, counts, indices)


def _mesh(path, points, counts, indices) -> MeshData:
    if not len(counts):
        raise UserError(f"{path}: no faces")
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        raise UserError(f"{path}: vertex {int(np.flatnonzero(bad)[0])} is not finite")
    return MeshData(points, np.asarray(counts, dtype=np.int32), np.asarray(indices, dtype=np.int32))


def read_mesh(path) -> MeshData:
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext == ".obj":
        return read_obj(read_bytes(path), path)
    if ext == ".ply":
        return read_ply_mesh(read_bytes(path), path)
    raise UserError(f"{path}: unknown head mesh extension {ext or '(none)'!r}: expected .obj or .ply")
