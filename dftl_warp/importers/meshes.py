"""Head meshes for ``dftl-warp import --head``: Wavefront OBJ (``v`` and ``f`` lines; ``v/vt/vn``
and negative indices; every object and group merged; texture, normal, material and group
statements skipped with one warning counting them; unknown statements and free-form geometry are
errors naming the line) and PLY (``vertex`` x y z and ``face`` with a
``vertex_indices`` or ``vertex_index`` list). Returns points (N, 3), faceVertexCounts and
faceVertexIndices as USD wants them."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import UserError, plural
from ._binary import read_bytes


@dataclass
class MeshData:
    points: np.ndarray
    face_counts: np.ndarray
    face_indices: np.ndarray
    #: one-line notes about what the reader skipped
    warnings: list[str] = field(default_factory=list)


#: OBJ statements a collider does not use, skipped with one warning that counts them: texture,
#: normal and parameter-space vertices, materials, smoothing, object and group names, display and
#: render attributes, and the elements that are no surface (points ``p``, polylines ``l``)
IGNORED = ("vt", "vn", "vp", "mtllib", "usemtl", "s", "o", "g", "mg", "usemap", "maplib", "lod", "bevel",
           "c_interp", "d_interp", "shadow_obj", "trace_obj", "p", "l")
#: free-form curves and surfaces (not tessellated here): an error, since the head would lose them
FREE_FORM = ("cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp",
             "end", "con", "ctech", "stech")


def obj_statements(text: str):
    """(line number, words) of each statement of an OBJ text: comments (``#`` to the end of the
    line) and blank lines left out, a line ending in ``\\`` joined to the next (numbered as its first)."""
    pending, first = [], None
    for no, line in enumerate(text.splitlines(), start=1):
        line = line.split("#", 1)[0].rstrip()
        more = line.endswith("\\")
        pending.append(line[:-1] if more else line)
        first = no if first is None else first
        if more:
            continue
        words = " ".join(pending).split()
        if words:
            yield first, words
        pending, first = [], None
    if pending and " ".join(pending).split():
        yield first, " ".join(pending).split()


def read_obj(data: bytes, path: str) -> MeshData:
    """An OBJ head mesh: ``v`` (x y z, then a weight or a colour, which are ignored) and ``f`` (``v``,
    ``v/vt``, ``v//vn`` or ``v/vt/vn``; 1-based, negative from the last vertex so far). What
    :data:`IGNORED` lists is counted in one warning; anything else is an error naming the line."""
    text = data.decode("utf-8", errors="replace").removeprefix("\ufeff")  # a BOM, as Windows editors save
    points, counts, indices, lines = [], [], [], []
    seen = {"vt": 0, "vn": 0}
    skipped: dict[str, int] = {}
    for no, words in obj_statements(text):
        key = words[0]
        where = f"{path}: line {no}"
        if key == "v":
            points.append(_obj_vertex(words, where, skipped))
        elif key == "f":
            face = [_obj_corner(w, len(points), seen, where) for w in words[1:]]
            if len(face) < 3:
                raise UserError(f"{where}: a face needs at least 3 vertices")
            counts.append(len(face))
            indices.extend(face)
            lines.append(no)
        elif key in IGNORED:
            seen[key] = seen.get(key, 0) + 1       # vt, vn: the range of the faces' texture, normal indices
            skipped[key] = skipped.get(key, 0) + 1
        elif key in FREE_FORM:
            raise UserError(f"{where}: free-form geometry ({key!r}) is not read: export the head as polygons (f)")
        else:
            raise UserError(f"{where}: unknown OBJ statement {' '.join(words)[:60]!r}")
    mesh = _mesh(path, np.array(points, dtype=np.float64).reshape(-1, 3), counts, indices,
                 lambda k, corners: f"line {lines[k]}: f {' '.join(str(i + 1) for i in corners)}")
    if skipped:
        listed = ", ".join(f"{n} {k}" for k, n in skipped.items())
        mesh.warnings.append(f"{path}: ignored what a collider does not use: {listed}")
    return mesh


def _obj_vertex(words, where: str, skipped: dict) -> list[float]:
    """x, y, z of a ``v`` statement; a weight or colour after them is counted in ``skipped``."""
    try:
        values = [float(w) for w in words[1:]]
    except ValueError:
        values = None
    if values is None or len(values) not in (3, 4, 6, 7):
        raise UserError(f"{where}: bad vertex {' '.join(words)[:60]!r}: expected x y z (then w, or r g b)")
    if len(values) > 3:
        skipped["v extras (w or r g b)"] = skipped.get("v extras (w or r g b)", 0) + 1
    return values[:3]


def _obj_corner(word: str, num_points: int, seen: dict, where: str) -> int:
    """The 0-based vertex index of a face corner ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``; its
    texture and normal indices are checked against the ``vt``/``vn`` statements so far."""
    parts = word.split("/")
    if len(parts) > 3 or (len(parts) == 2 and not parts[1]):
        raise UserError(f"{where}: bad face vertex {word!r}: expected v, v/vt, v//vn or v/vt/vn")
    i = _obj_index(parts[0], num_points, "vertex", word, where)
    for text, kind in zip(parts[1:], ("vt", "vn")):
        if text:
            _obj_index(text, seen[kind], kind, word, where)
    return i


def _obj_index(text: str, count: int, what: str, word: str, where: str) -> int:
    """A 1-based OBJ index (negative: from the last of ``count`` so far) as a 0-based one."""
    try:
        i = int(text)
    except ValueError:
        raise UserError(f"{where}: bad face index {word!r}") from None
    k = i - 1 if i > 0 else count + i
    if i == 0 or not 0 <= k < count:
        have = f"1..{count} or -{count}..-1" if count else "none defined before this line"
        raise UserError(f"{where}: face {what} index {i} in {word!r} is out of range ({have})")
    return k


def read_ply_mesh(data: bytes, path: str) -> MeshData:
    from .ply import read_ply, unused_note, vertex_positions

    elements = read_ply(data, path)
    points = vertex_positions(elements, path)
    face = elements.get("face")
    if face is None:
        raise UserError(f"{path}: no 'face' element: not a mesh")
    key = "vertex_indices" if "vertex_indices" in face.data else "vertex_index"
    lists = face.data.get(key)
    if not isinstance(lists, list):
        raise UserError(f"{path}: element 'face' has no 'vertex_indices' list")
    counts = [len(f) for f in lists]
    bad = [k for k, c in enumerate(counts) if c < 3]
    if bad:
        raise UserError(f"{path}: face {bad[0]}: a face needs at least 3 vertices")
    values = np.concatenate([np.asarray(f, dtype=np.float64) for f in lists]) if lists else np.zeros(0)
    owner = np.repeat(np.arange(len(counts)), counts)
    bad = np.flatnonzero((values != np.round(values)) | (values < 0) | (values >= points.shape[0]))
    if bad.size:
        i = int(bad[0])
        k = int(owner[i])
        what = "is not a whole number" if values[i] != np.round(values[i]) else \
            f"is out of range (0..{points.shape[0] - 1})"
        raise UserError(f"{path}: {face.where(k)}: face {k}: vertex index {values[i]:g} {what}")
    mesh = _mesh(path, points, counts, values.astype(np.int64), lambda k, corners: f"{face.where(k)}: face {k}: "
                 f"{key} {' '.join(map(str, corners))}")
    note = unused_note(elements, {"vertex": {"x", "y", "z"}, "face": {key}}, path, "a collider uses only the "
                       "vertices' positions and the faces")
    if note:
        mesh.warnings.append(note)
    return mesh


def _mesh(path, points, counts, indices, where) -> MeshData:
    """MeshData of the faces (``where(k, corners)``: face k as the file has it, for messages), without the
    repeats of a vertex a face lists (:func:`without_repeats`), with one warning if there are any."""
    if not len(counts):
        raise UserError(f"{path}: no faces")
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        raise UserError(f"{path}: vertex {int(np.flatnonzero(bad)[0])} is not finite")
    counts, indices, note = without_repeats(np.asarray(counts, dtype=np.int64), np.asarray(indices, np.int64),
                                            path, where)
    if not len(counts):
        raise UserError(f"{note}: no faces left")
    return MeshData(points, counts.astype(np.int32), indices.astype(np.int32), [note] if note else [])


def without_repeats(counts: np.ndarray, indices: np.ndarray, path: str, where):
    """(counts, indices, warning or "") of polygons that name a vertex twice: a corner repeated next
    to itself (``f 1 2 3 3``, also last to first: ``f 1 2 3 1``) is one corner; a face left with
    fewer than 3, or that still comes back to a vertex (``f 1 2 1 3``), has no area of its own
    and is dropped. Such faces would give the collider triangles of zero area, with no normal."""
    owner = np.repeat(np.arange(len(counts)), counts)
    pairs = np.unique(np.stack([owner, indices], axis=1), axis=0)
    repeats = np.flatnonzero(np.bincount(pairs[:, 0], minlength=len(counts)) < counts)
    if not repeats.size:
        return counts, indices, ""
    starts = np.cumsum(counts) - counts
    faces = np.split(indices, starts[1:])
    dropped = fixed = 0
    for k in repeats:
        face = faces[k]
        face = face[face != np.roll(face, 1)] if len(np.unique(face)) > 1 else face[:1]
        if len(face) < 3 or len(np.unique(face)) < len(face):
            face, dropped = face[:0], dropped + 1
        else:
            fixed += 1
        faces[k] = face
    k = int(repeats[0])
    done = ", ".join(x for x in (f"{dropped} dropped (no area)" if dropped else "",
                                 f"{fixed} kept without the repeated corner" if fixed else "") if x)
    verb = "names" if len(repeats) == 1 else "name"
    note = (f"{path}: {plural(len(repeats), 'face')} of {len(counts)} {verb} a vertex twice (first: "
            f"{where(k, indices[starts[k]:starts[k] + counts[k]].tolist())}): {done}")
    new_counts = np.array([len(f) for f in faces], dtype=np.int64)
    keep = new_counts > 0
    return new_counts[keep], np.concatenate([faces[i] for i in np.flatnonzero(keep)] or [indices[:0]]), note


def read_mesh(path) -> MeshData:
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext == ".obj":
        return read_obj(read_bytes(path), path)
    if ext == ".ply":
        return read_ply_mesh(read_bytes(path), path)
    raise UserError(f"{path}: unknown head mesh extension {ext or '(none)'!r}: expected .obj or .ply")
