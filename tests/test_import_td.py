"""``dftl-warp import`` on files a researcher writes by hand: values USD's float32 cannot hold,
data a reader skips, head meshes from other tools. One line naming the file and where (exit 2,
nothing written) or one warning; never a traceback or a stage holding inf."""

from __future__ import annotations

import re
import struct
import numpy as np
import pytest

import test_importers as ti
from test_import_input import refused, strands, warned

from dftl_warp.importers import GroomImportWarning  # noqa: F401  (the warnings' class)


def double_ply(path, points, counts, widths):
    """A binary PLY of double x y z width and a strand element of vertex counts."""
    head = ("ply\nformat binary_little_endian 1.0\n"
            f"element vertex {len(points)}\nproperty double x\nproperty double y\nproperty double z\n"
            f"property double width\nelement strand {len(counts)}\nproperty int vertex_count\nend_header\n")
    rows = np.zeros(len(points), [("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("w", "<f8")])
    rows["x"], rows["y"], rows["z"] = np.asarray(points, float).T
    rows["w"] = widths
    path.write_bytes(head.encode() + rows.tobytes() + np.asarray(counts, "<i4").tobytes())
    return path


def test_points_and_widths_beyond_float32_are_refused_naming_strand_and_point(tmp_path, capsys):
    """A double PLY with a coordinate or width of 1e300 was written as inf into the stage (numpy's
    overflow warning on stderr, exit 0); simulate then refused the stage. Now the import refuses."""
    pts, counts = strands([3, 2], step=10.0)
    big = pts.astype(float)
    big[4, 0] = 1e300
    src, out = double_ply(tmp_path / "big.ply", big, counts, 0.05), tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out)], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(src))}: strand 1: point 1 = \(1e\+300, 0, -40\) does not fit "
            r"float32 \(at most 3\.403e\+38\), the type of USD's points and widths: is the unit right\?$")
    widths = np.full(5, 0.05)
    widths[3] = 1e300
    src = double_ply(tmp_path / "wide.ply", pts, counts, widths)
    refused(["import", str(src), "-o", str(out)], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(src))}: strand 1: width 1e\+300 at point 0 does not fit float32")
    refused(["import", str(double_ply(tmp_path / "ok.ply", pts, counts, 0.05)), "-o", str(out), "--width", "1e40"],
            capsys, str(out), r"^dftl-warp: error: width / --width = 1e\+40: expected a finite number > 0 \(at most "
                              r"3\.403e\+38, USD's float32\)$")


def test_a_head_vertex_beyond_float32_is_refused_naming_the_vertex(tmp_path, capsys):
    pts, counts = strands([3, 3], step=10.0)
    src = ti.write_hair(tmp_path / "g.hair", pts, counts)
    head = tmp_path / "head.obj"
    head.write_text("v 0 0 0\nv 1 0 0\nv 1e300 1 0\nf 1 2 3\n")
    out = tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out), "--head", str(head)], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(head))}: vertex 2 = \(1e\+300, 1, 0\) does not fit float32")


def test_strands_kept_after_subsampling_are_named_by_their_index_in_the_file(tmp_path, capsys):
    pts, counts = strands([3, 3, 3], step=10.0)
    big = pts.astype(float)
    big[7, 1] = -1e39
    src, out = double_ply(tmp_path / "big.ply", big, counts, 0.05), tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out), "--every", "2"], capsys, str(out), r": strand 2: point 1 = ")
    result, notes = warned(src, out, max_strands=1)      # strand 0 only: nothing beyond float32 is left
    stage, curves = ti.open_curves(out)
    points = np.array(curves.GetPointsAttr().Get())
    assert result.strands == 1 and points.shape == (3, 3) and np.isfinite(points).all()


def ply_head(path, faces, *, item="int", binary=False):
    """A PLY head: the unit square's 4 corners and ``faces`` (lists of indices) of ``item`` type."""
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    head = ("ply\nformat " + ("binary_big_endian" if binary else "ascii") + " 1.0\nelement vertex 4\n"
            "property float x\nproperty float y\nproperty float z\n"
            f"element face {len(faces)}\nproperty list uchar {item} vertex_indices\nend_header\n").encode()
    if binary:
        kind = {"int": ">i4", "float": ">f4"}[item]
        body = corners.astype(">f4").tobytes() + b"".join(bytes([len(f)]) + np.asarray(f, kind).tobytes() for f in faces)
    else:
        body = ("".join(f"{x:g} {y:g} {z:g}\n" for x, y, z in corners)
                + "".join(f"{len(f)} {' '.join(f'{i:g}' for i in f)}\n" for f in faces)).encode()
    path.write_bytes(head + body)
    return path


@pytest.mark.parametrize("faces, item, binary, where", [
    ([[0, 1, 2], [0, 2, 2.5]], "float", False, r"line 15: face 1: vertex index 2\.5 is not a whole number"),
    ([[0, 1, 2], [0, 2, 2.5]], "float", True, r"offset \d+: face 1: vertex index 2\.5 is not a whole number"),
    ([[0, 1, 2, 3], [0, 2, -1]], "int", False, r"line 15: face 1: vertex index -1 is out of range \(0\.\.3\)"),
    ([[0, 1, 2, 3], [0, 2, 4]], "int", True, r"offset 231: face 1: vertex index 4 is out of range \(0\.\.3\)"),
])
def test_ply_head_face_indices_name_the_face_and_its_line_or_offset(tmp_path, capsys, faces, item, binary, where):
    """A PLY head with float face indices had 2.5 read as vertex 2 without a word, and an index
    out of range named neither the face nor where it is; now both name the face, line or offset."""
    pts, counts = strands([3, 3], step=10.0)
    src = ti.write_hair(tmp_path / "g.hair", pts, counts)
    head, out = ply_head(tmp_path / "head.ply", faces, item=item, binary=binary), tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out), "--head", str(head)], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(head))}: {where}$")


def test_ply_head_with_whole_float_indices_and_quads_is_read(tmp_path):
    pts, counts = strands([3, 3], step=10.0)
    src = ti.write_hair(tmp_path / "g.hair", pts, counts)
    head = ply_head(tmp_path / "head.ply", [[0, 1, 2, 3]], item="float", binary=True)
    result, _ = warned(src, tmp_path / "o.usda", head=head)
    stage, _ = ti.open_curves(tmp_path / "o.usda")
    from pxr import UsdGeom

    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Groom/Head"))
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [4]
    assert list(mesh.GetFaceVertexIndicesAttr().Get()) == [0, 1, 2, 3]


def _head_faces(tmp_path, head):
    pts, counts = strands([3, 3], step=10.0)
    _, notes = warned(ti.write_hair(tmp_path / "g.hair", pts, counts), tmp_path / "o.usda", head=head)
    stage, _ = ti.open_curves(tmp_path / "o.usda")
    from pxr import UsdGeom

    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Groom/Head"))
    faces = np.split(np.asarray(mesh.GetFaceVertexIndicesAttr().Get()),
                     np.cumsum(mesh.GetFaceVertexCountsAttr().Get())[:-1])
    return [f.tolist() for f in faces], [n for n in notes if "twice" in n]


def test_head_faces_that_name_a_vertex_twice_get_one_warning_and_no_zero_area_face(tmp_path):
    """``f 1 1 2`` and ``f 1 2 3 1`` were written to the collider as they were, without a word:
    triangles of zero area. Now the first is dropped, the second keeps its three corners."""
    head = tmp_path / "head.obj"
    head.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 1 2\nf 1 2 4 1\nf 1 2 1 3\n")
    faces, notes = _head_faces(tmp_path, head)
    assert faces == [[0, 2, 1], [1, 3, 0]]
    assert notes == [f"{head}: 3 faces of 4 name a vertex twice (first: line 6: f 1 1 2): 2 dropped (no area), "
                     "1 kept without the repeated corner"]
    head = ply_head(tmp_path / "head.ply", [[0, 1, 2], [3, 3, 1]])
    faces, notes = _head_faces(tmp_path, head)
    assert faces == [[0, 1, 2]]
    assert notes == [f"{head}: 1 face of 2 names a vertex twice (first: line 15: face 1: vertex_indices 3 3 1): "
                     "1 dropped (no area)"]


def test_a_head_of_only_faces_that_name_a_vertex_twice_is_refused(tmp_path, capsys):
    pts, counts = strands([3, 3], step=10.0)
    src, out = ti.write_hair(tmp_path / "g.hair", pts, counts), tmp_path / "o.usda"
    head = tmp_path / "head.obj"
    head.write_text("v 0 0 0\nv 1 0 0\nf 1 1 2\n")
    refused(["import", str(src), "-o", str(out), "--head", str(head)], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(head))}: 1 face of 1 names a vertex twice .*: no faces left$")


def test_an_obj_head_saved_with_a_utf8_byte_order_mark_is_read(tmp_path):
    """An OBJ saved by a Windows editor starts with a UTF-8 BOM: it was refused as an unknown
    statement '\\ufeffv 0 0 0' on line 1."""
    pts, counts = strands([3, 3], step=10.0)
    src = ti.write_hair(tmp_path / "g.hair", pts, counts)
    head = tmp_path / "head.obj"
    head.write_bytes(b"\xef\xbb\xbfv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n")
    warned(src, tmp_path / "o.usda", head=head)
    stage, _ = ti.open_curves(tmp_path / "o.usda")
    from pxr import UsdGeom

    assert len(UsdGeom.Mesh(stage.GetPrimAtPath("/Groom/Head")).GetPointsAttr().Get()) == 3


# -- what a file holds beyond positions and widths is named in one warning ------------------------


def test_hair_transparency_and_colour_arrays_are_named_as_not_imported(tmp_path):
    """Colours and transparency of a .hair were dropped without a word (TressFX's thickness had a
    warning); now one warning names them."""
    pts, counts = strands([3, 3], step=10.0)
    src = ti.write_hair(tmp_path / "g.hair", pts, counts)
    data = bytearray(src.read_bytes())
    arrays = struct.unpack_from("<I", data, 12)[0] | 8 | 16                 # transparency and colours
    struct.pack_into("<I", data, 12, arrays)
    src.write_bytes(bytes(data) + bytes(4 * len(pts)) + bytes(12 * len(pts)))
    _, notes = warned(src, tmp_path / "o.usda")
    assert f"{src}: not imported: the transparency and colors arrays (only points and thickness are imported)" in notes
    _, notes = warned(ti.write_hair(tmp_path / "plain.hair", pts, counts), tmp_path / "o.usda")
    assert not [n for n in notes if "not imported" in n]


def test_tfx_uvs_and_colours_are_named_as_not_imported(tmp_path):
    pts, _ = strands([4, 4], step=0.02)
    xyzw = np.concatenate([pts, np.ones((8, 1), np.float32)], axis=1).astype("<f4").tobytes()
    head = struct.pack("<f7I", 4.0, 2, 4, 160, 288, 304, 0, 368) + bytes(128)
    src = tmp_path / "g.tfx"
    src.write_bytes(head + xyzw + bytes(16) + bytes(64) + bytes(128))
    _, notes = warned(src, tmp_path / "o.usda")
    assert (f"{src}: not imported: float2 strand UVs, float2 vertex UVs, float4 vertex colours (only positions are "
            "imported)") in notes


def test_counts_of_one_strand_are_singular(tmp_path, capsys):
    """'all 1 strands get 8e-05 stage units', '1 strands, 3 points': now '1 strand'."""
    from dftl_warp import cli

    pts, counts = strands([3], step=0.02)
    src = ti.write_hair(tmp_path / "g.hair", pts, counts)
    assert cli.main(["import", str(src), "-o", str(tmp_path / "o.usda")]) == 0
    out, err = capsys.readouterr()
    assert out.startswith(f"{tmp_path / 'o.usda'}: 1 strand, 3 points from "), out
    assert "no hair widths in the file; its 1 strand gets " in err and "1 strands" not in err, err


def test_tfx_vertices_pinned_past_the_root_get_one_warning(tmp_path):
    """TressFX marks immovable vertices with w = 0; vertex 0 alone is pinned as the root, and other
    pins were dropped without a word. Now one warning counts them and names the first."""
    pts, _ = strands([4, 4, 4], step=0.02)
    src = ti.write_tfx(tmp_path / "g.tfx", pts, 4)          # w = 0 at the roots only
    _, notes = warned(src, tmp_path / "o.usda")
    assert not [n for n in notes if "pin more than" in n]
    data = bytearray(src.read_bytes())
    for vertex in (1, 5, 6):                                # strand 0 vertex 1, strand 1 vertices 1 and 2
        struct.pack_into("<f", data, 160 + 16 * vertex + 12, 0.0)
    src.write_bytes(bytes(data))
    _, notes = warned(src, tmp_path / "o.usda")
    assert [n for n in notes if "pin more than" in n] == [
        f"{src}: 2 strands of 3 pin more than the root: 3 vertices after vertex 0 have w = 0 (immovable; first: "
        "strand 0, vertex 1); only each strand's root is pinned, the others move freely"]


def test_ply_properties_and_elements_a_reader_does_not_use_are_named(tmp_path):
    """Vertex colours and normals, a face element, or a per-vertex list of a strand PLY (and a
    head PLY's normals and UVs) were skipped silently, while an OBJ head's vt/vn were warned about."""
    pts, counts = strands([3, 3], step=10.0)
    rows = "".join(f"{x:g} {y:g} {z:g} 0.05 255 0.5 2 0.1 0.2\n" for x, y, z in pts)
    src = tmp_path / "g.ply"
    src.write_text("ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
                   "property float thickness\nproperty uchar red\nproperty float nx\nproperty list uchar float uv\n"
                   "element strand 2\nproperty int nsegs\nproperty int group\nelement face 1\n"
                   "property list uchar int vertex_indices\nend_header\n" + rows + "2 7\n2 7\n3 0 1 2\n")
    result, notes = warned(src, tmp_path / "o.usda")
    assert result.widths == "per vertex, from the file"
    assert [n for n in notes if "not imported" in n] == [
        f"{src}: not imported: vertex properties 'red', 'nx', 'uv'; strand property 'group'; element 'face' (1 row) "
        "(only positions, widths and strands are imported)"]
    head = tmp_path / "head.ply"
    head.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "property float nx\nproperty float s\nelement face 1\nproperty list uchar int vertex_indices\n"
                    "end_header\n0 0 0 0 0\n1 0 0 0 1\n0 1 0 1 0\n3 0 1 2\n")
    _, notes = warned(ti.write_hair(tmp_path / "g.hair", pts, counts), tmp_path / "o.usda", head=head)
    assert f"{head}: not imported: vertex properties 'nx', 's' (a collider uses only the vertices' positions and " \
           "the faces)" in notes


@pytest.mark.parametrize("delimit", ["strand", "strand_id", "edge"])
def test_a_ply_of_only_what_is_imported_gets_no_such_warning(tmp_path, delimit):
    pts, counts = strands([3, 3], step=10.0)
    src = ti.write_ply(tmp_path / "g.ply", pts, counts, widths=np.full(6, 0.05), delimit=delimit)
    _, notes = warned(src, tmp_path / "o.usda")
    assert not [n for n in notes if "not imported" in n]


def test_dropping_every_strand_for_nan_says_so_and_subsampling_names_the_file(tmp_path, capsys):
    """--drop-nonfinite on a file whose every strand has a NaN was refused as having "no strands
    with 2 or more vertices" (they had 3); the --every note named no file."""
    pts, counts = strands([3, 3], step=0.02)
    pts[1, 0] = pts[4, 2] = np.nan
    src, out = ti.write_strand_list(tmp_path / "g.data", pts, counts), tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out), "--drop-nonfinite"], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(src))}: no strands left to import: all 2 have NaN/inf points "
            r"\(--drop-nonfinite\)$")
    pts, counts = strands([3, 3, 3], step=0.02)
    src = ti.write_strand_list(tmp_path / "g.data", pts, counts)
    _, notes = warned(src, out, every=2)
    assert f"{src}: kept 2 of 3 strands (--every/--max-strands)" in notes
