"""``dftl-warp import`` on degenerate or malformed input and bad arguments (CPU only): one line
naming the file and the offset, line, strand or option, exit status 2, nothing written; what is
kept or dropped is one warning. Every test writes its own small files."""

from __future__ import annotations

import math
import os
import re
import struct
import warnings

import numpy as np
import pytest

import test_importers as ti
from dftl_warp.errors import UserError
from dftl_warp.importers import GroomImportWarning, read_groom
from dftl_warp.importers.convert import import_groom


def refused(argv, capsys, out, pattern):
    """Run the CLI: exit 2, one stderr line matching ``pattern``, no traceback, ``out`` not written
    (and no temporary file left next to it)."""
    code, stdout, err = ti.run_cli(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert re.search(pattern, lines[0]), lines[0]
    assert not os.path.exists(out)
    assert not [f for f in os.listdir(os.path.dirname(out)) if f.startswith(f".{os.path.basename(out)}")]
    return lines[0]


def warned(src, out, **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", GroomImportWarning)
        result = import_groom(src, out, **kwargs)
    return result, [str(w.message) for w in caught if issubclass(w.category, GroomImportWarning)]


def strands(counts, step=0.1):
    """Points of strands with ``counts`` vertices hanging along -z, all distinct."""
    n = int(sum(counts))
    pts = np.zeros((n, 3), np.float32)
    pts[:, 2] = -np.arange(n) * step
    pts[:, 0] = np.arange(n) * 0.01
    return pts, np.asarray(counts, np.int64)


# -- 1. .hair: 1-vertex (0-segment) strands are dropped with a warning, as in every format ---------


def test_hair_zero_segment_strands_dropped_like_other_formats(tmp_path):
    pts, counts = strands([4, 1, 4])
    thick = np.linspace(0.01, 0.02, len(pts)).astype(np.float32)
    hair = ti.write_hair(tmp_path / "s.hair", pts, counts, thick)
    data = ti.write_strand_list(tmp_path / "s.data", pts, counts)
    results = {}
    for src in (hair, data):
        result, notes = warned(src, tmp_path / f"{src.suffix[1:]}.usda")
        drops = [n for n in notes if "fewer than 2 vertices" in n]
        assert drops == [f"{src}: dropped 1 of 3 strands with fewer than 2 vertices"]
        results[src.suffix] = result
        _, curves = ti.open_curves(tmp_path / f"{src.suffix[1:]}.usda")
        assert list(curves.GetCurveVertexCountsAttr().Get()) == [4, 4]
        keep = np.repeat([True, False, True], counts)
        np.testing.assert_array_equal(np.array(curves.GetPointsAttr().Get(), np.float32), pts[keep])
        if src.suffix == ".hair":  # per-vertex widths dropped with their points
            np.testing.assert_array_equal(np.array(curves.GetWidthsAttr().Get(), np.float32), thick[keep])
    assert results[".hair"].strands == results[".data"].strands == 2


def test_hair_without_segments_array_and_zero_d_segments(tmp_path, capsys):
    # no segments array, d_segments = 0: every strand is one point
    pts, counts = strands([1, 1, 1])
    src = ti.write_hair(tmp_path / "z.hair", pts, counts, segments_array=False)
    groom = read_groom(src)
    assert groom.num_strands == 0 and any("dropped 3 of 3" in w for w in groom.warnings)
    out = tmp_path / "z.usda"
    refused(["import", str(src), "-o", str(out)], capsys, str(out), rf"^dftl-warp: error: {re.escape(str(src))}: "
            r"no strands with 2 or more vertices")


def test_all_single_vertex_strands_refused_in_every_format(tmp_path, capsys):
    pts, counts = strands([1, 1])
    files = [ti.write_hair(tmp_path / "a.hair", pts, counts), ti.write_strand_list(tmp_path / "a.data", pts, counts),
             ti.write_ply(tmp_path / "a.ply", pts, counts)]
    for src in files:
        out = tmp_path / f"{src.suffix[1:]}.usda"
        line = refused(["import", str(src), "-o", str(out)], capsys, str(out), r"no strands with 2 or more vertices")
        assert line == f"dftl-warp: error: {src}: no strands with 2 or more vertices to import"


# -- 2. strand PLY: malformed files are refused with the line or offset --------------------------

HEAD = ["ply", "format ascii 1.0", "element vertex 6", "property float x", "property float y", "property float z",
        "element strand 2", "property int vertex_count", "end_header"]
ROWS = ["0 0 0", "0 -1 0", "0 -2 0", "1 0 0", "1 -1 0", "1 -2 0", "3", "3"]


def ascii_ply(tmp_path, name, head=HEAD, rows=ROWS, tail=""):
    p = tmp_path / name
    p.write_text("\n".join(head + rows) + "\n" + tail)
    return p


def binary_ply(tmp_path, name, nsegs_type="uchar", nsegs=(2, 2), extra_header="", tail=b""):
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 6\nproperty float x\nproperty float y\n"
            f"property float z\nelement strand 2\nproperty {nsegs_type} nsegs\n{extra_header}end_header\n").encode()
    pts, _ = strands([3, 3])
    dtype = {"uchar": "<u1", "float": "<f4", "double": "<f8"}[nsegs_type]
    p = tmp_path / name
    p.write_bytes(head + pts.astype("<f4").tobytes() + np.asarray(nsegs, dtype).tobytes() + tail)
    return p, len(head)


def test_ply_valid_ascii_and_binary_still_read(tmp_path):
    assert list(read_groom(ascii_ply(tmp_path, "ok.ply")).counts) == [3, 3]
    assert list(read_groom(ascii_ply(tmp_path, "blank.ply", tail="\n  \n")).counts) == [3, 3]  # blank lines
    crlf = tmp_path / "crlf.ply"
    crlf.write_bytes(("\r\n".join(HEAD + ROWS) + "\r\n").encode())
    assert list(read_groom(crlf).counts) == [3, 3]
    assert list(read_groom(binary_ply(tmp_path, "ok_bin.ply")[0]).counts) == [3, 3]
    assert list(read_groom(binary_ply(tmp_path, "f.ply", "float", (2.0, 2.0))[0]).counts) == [3, 3]


def test_ply_ascii_row_with_wrong_number_count_names_its_line(tmp_path, capsys):
    rows = list(ROWS)
    rows[1], rows[2] = "0 -1", "0 -2 0 7"  # 2 then 4 numbers: the total still adds up
    src = ascii_ply(tmp_path, "shifted.ply", rows=rows)
    assert src.read_text().splitlines()[10] == "0 -1"  # line 11
    out = tmp_path / "o.usda"
    line = refused(["import", str(src), "-o", str(out)], capsys, str(out), r"line 11: element 'vertex' row 1: "
                   r"expected 3 numbers, got '0 -1'")
    assert line.startswith(f"dftl-warp: error: {src}: line 11: ")
    # a list element's row with numbers left over
    head = HEAD[:6] + ["element strand 2", "property list uchar int vertex_indices", "end_header"]
    src = ascii_ply(tmp_path, "listrow.ply", head=head, rows=ROWS[:6] + ["3 0 1 2", "3 3 4 5 9"])
    with pytest.raises(UserError, match=r"listrow\.ply: line 17: element 'strand' row 1: cannot parse"):
        read_groom(src)


def test_ply_line_numbers_count_from_the_first_line(tmp_path):
    rows = list(ROWS)
    rows[0] = "0 0 x"
    src = ascii_ply(tmp_path, "bad.ply", rows=rows)
    assert src.read_text().splitlines()[9] == "0 0 x"
    with pytest.raises(UserError, match=r"bad\.ply: line 10: element 'vertex' row 0"):
        read_groom(src)


def test_ply_trailing_data_is_an_error_like_data_and_bin(tmp_path, capsys):
    src = ascii_ply(tmp_path, "trail.ply", tail="GARBAGE 1 2 3\n")
    out = tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out)], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(src))}: line 18: 'GARBAGE 1 2 3' after the last element "
            r"\('strand', 2 rows\): the element counts do not add up")
    src, header = binary_ply(tmp_path, "trailbin.ply", tail=bytes(100))
    end = header + 6 * 12 + 2
    refused(["import", str(src), "-o", str(out)], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(src))}: offset {end}: 100 bytes after the last element "
            r"\('strand', 2 rows\)")
    # a miscounted strand element still names the counts first
    bad = ascii_ply(tmp_path, "count.ply", head=[h.replace("strand 2", "strand 1") for h in HEAD])
    with pytest.raises(UserError, match=r"gives 3 vertices for 1 strand but"):
        read_groom(bad)
    # head meshes read the same way
    mesh = tmp_path / "head.ply"
    mesh.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
                    "3 0 1 2\n9 9 9\n")
    good = ti.write_strand_list(tmp_path / "g.data", *strands([3, 3]))
    refused(["import", str(good), "-o", str(out), "--head", str(mesh)], capsys, str(out),
            rf"{re.escape(str(mesh))}: line 14: '9 9 9' after the last element")


def test_ply_element_with_rows_but_no_properties(tmp_path, capsys):
    head = HEAD[:-1] + ["element junk 99999999999", "end_header"]
    src = ascii_ply(tmp_path, "noprop.ply", head=head)
    out = tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out)], capsys, str(out),
            rf"{re.escape(str(src))}: line 9: element 'junk' has 99999999999 rows but no properties")
    src, _ = binary_ply(tmp_path, "noprop_bin.ply", extra_header="element junk 5\nelement empty 0\n")
    with pytest.raises(UserError, match=r"line 9: element 'junk' has 5 rows but no properties"):
        read_groom(src)


@pytest.mark.parametrize("kind", ["float", "double"])
def test_ply_non_integer_counts_are_errors(tmp_path, capsys, kind):
    src, header = binary_ply(tmp_path, "floatsegs.ply", kind, (2.0, 2.7))
    out = tmp_path / "o.usda"
    size = 4 if kind == "float" else 8
    refused(["import", str(src), "-o", str(out)], capsys, str(out),
            rf"{re.escape(str(src))}: offset {header + 72 + size}: element 'strand' row 1 property 'nsegs' = 2\.7: "
            r"expected a whole number")
    src, _ = binary_ply(tmp_path, "nansegs.ply", kind, (float("nan"), 2.0))
    with pytest.raises(UserError, match=r"row 0 property 'nsegs' = nan: expected a whole number"):
        read_groom(src)
    # ASCII: the line
    head = HEAD[:7] + ["property float vertex_count", "end_header"]
    src = ascii_ply(tmp_path, "floatcount.ply", head=head, rows=ROWS[:6] + ["3", "3.5"])
    with pytest.raises(UserError, match=r"floatcount\.ply: line 17: element 'strand' row 1 property 'vertex_count'"):
        read_groom(src)


def test_ply_non_integer_edge_index_is_an_error(tmp_path):
    head = HEAD[:6] + ["element edge 2", "property float vertex1", "property float vertex2", "end_header"]
    src = ascii_ply(tmp_path, "edge.ply", head=head, rows=ROWS[:6] + ["0 1", "1.5 2"])
    with pytest.raises(UserError, match=r"edge\.ply: line 18: element 'edge' row 1 property 'vertex1' = 1\.5"):
        read_groom(src)


def test_ply_property_declared_twice(tmp_path, capsys):
    head = HEAD[:6] + ["property float x"] + HEAD[6:]
    src = ascii_ply(tmp_path, "dupx.ply", head=head, rows=[r + " 5" for r in ROWS[:6]] + ROWS[6:])
    out = tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out)], capsys, str(out),
            rf"{re.escape(str(src))}: line 7: property 'x' of element 'vertex' is declared twice")


# -- 3. --head-friction: finite and >= 0, checked before anything is written ----------------------


def head_files(tmp_path):
    src = ti.write_strand_list(tmp_path / "g.data", *strands([3, 3]))
    obj = tmp_path / "head.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    return src, obj


@pytest.mark.parametrize("value", ["-1", "nan", "inf", "-inf"])
def test_head_friction_refused_in_one_line(tmp_path, capsys, value):
    src, obj = head_files(tmp_path)
    out = tmp_path / "o.usda"
    line = refused(["import", str(src), "-o", str(out), "--head", str(obj), f"--head-friction={value}"], capsys,
                   str(out), r"--head-friction")
    expected = ">= 0" if value == "-1" else "a finite number >= 0"
    assert line == f"dftl-warp: error: head_friction / --head-friction = {float(value)!r}: dftl:friction must be " \
                   f"{expected}"
    with pytest.raises(ValueError, match=r"head_friction .*dftl:friction must be"):
        import_groom(src, out, head=obj, head_friction=float(value))
    assert not out.exists()


def test_head_friction_same_range_as_simulate(tmp_path):
    from dftl_warp.options import OPTIONS

    src, obj = head_files(tmp_path)
    assert OPTIONS["friction"].range_text == ">= 0"
    with pytest.raises(ValueError, match=r"dftl:friction must be a number >= 0$"):
        import_groom(src, tmp_path / "o.usda", head=obj, head_friction="0.3")
    warned(src, tmp_path / "o.usda", head=obj, head_friction=0)
    scene = ti.usd_reader().read_scene(str(tmp_path / "o.usda"))
    assert scene.colliders[0].friction == 0.0


def test_head_friction_without_head_warns(tmp_path):
    src, _ = head_files(tmp_path)
    _, notes = warned(src, tmp_path / "o.usda", head_friction=0.4)
    assert [n for n in notes if "--head-friction" in n] == [
        f"{src}: head_friction / --head-friction without a head mesh (--head); ignored"]


# -- 4. coincident consecutive points: kept, with one warning naming strand and points ------------


COINCIDE = re.compile(r": points \d+ and \d+ coincide")


def dup_file(tmp_path):
    pts, counts = strands([4, 4, 4])
    pts[4:8] = pts[4]           # strand 1: 4 identical points
    pts[9] = pts[8]             # strand 2: points 0 and 1 coincide
    return ti.write_strand_list(tmp_path / "dup.data", pts, counts), pts


def test_coincident_points_kept_with_one_warning(tmp_path, capsys):
    src, pts = dup_file(tmp_path)
    out = tmp_path / "o.usda"
    result, notes = warned(src, out)
    dup = [n for n in notes if COINCIDE.search(n)]
    assert len(dup) == 1
    assert dup[0].startswith(f"{src}: strand 1: points 0 and 1 coincide (a zero-length segment; 2 of 3 strands "
                             "have coincident consecutive points); kept, but the elastic solver")
    assert "--solver dftl" in dup[0]
    _, curves = ti.open_curves(out)
    np.testing.assert_array_equal(np.array(curves.GetPointsAttr().Get(), np.float32), pts)
    # the command prints it once, on one line, and exits 0
    code, _, err = ti.run_cli(["import", str(src), "-o", str(tmp_path / "c.usda")], capsys)
    assert code == 0 and len(COINCIDE.findall(err)) == 1
    assert [ln for ln in err.splitlines() if COINCIDE.search(ln)][0].startswith(f"dftl-warp: warning: {src}: strand 1:")


def test_coincident_points_after_resampling_and_subsampling(tmp_path):
    src, _ = dup_file(tmp_path)
    # resampling spreads strand 2's points; strand 1 has zero length and stays coincident
    _, notes = warned(src, tmp_path / "a.usda", segments=8)
    dup = [n for n in notes if COINCIDE.search(n)]
    assert len(dup) == 1 and "strand 1: points 0 and 1 coincide after --segments resampling" in dup[0]
    assert "1 of 3 strands" in dup[0]
    # strand 2 of the file is curve 1 of the output once strand 1 is left out
    _, notes = warned(src, tmp_path / "b.usda", max_strands=2)
    dup = [n for n in notes if COINCIDE.search(n)]
    assert len(dup) == 1 and "strand 2 (curve 1 of /Groom/Hair): points 0 and 1 coincide" in dup[0]


def test_points_distinct_only_in_float64_count_as_coincident(tmp_path):
    pts = np.array([[0, 0, 0], [1, 0, 0], [1 + 1e-12, 0, 0], [2, 0, 0]], np.float64)
    from dftl_warp.importers import Groom
    from dftl_warp.importers.convert import coincident_note

    note = coincident_note("f", Groom(pts, np.array([4])), False)
    assert note is not None and note.startswith("f: strand 0: points 1 and 2 coincide")
    assert coincident_note("f", Groom(pts[[0, 1, 3]], np.array([2, 1])), False) is None  # across strands


def test_no_coincidence_warning_for_clean_input(tmp_path):
    src = ti.write_strand_list(tmp_path / "g.data", *strands([3, 3]))
    _, notes = warned(src, tmp_path / "o.usda")
    assert not [n for n in notes if COINCIDE.search(n)]


# -- 5. .hair header: a bad default thickness is an error --------------------------------------


@pytest.mark.parametrize("value", [-0.5, float("nan"), float("inf")])
def test_hair_bad_default_thickness_refused(tmp_path, capsys, value):
    pts, counts = strands([4, 4])
    src = ti.write_hair(tmp_path / "t.hair", pts, counts, d_thickness=value)
    out = tmp_path / "o.usda"
    line = refused(["import", str(src), "-o", str(out)], capsys, str(out), r"d_thickness")
    assert line.startswith(f"dftl-warp: error: {src}: offset 20: d_thickness (the header's default thickness) = "
                           f"{value:g}: expected a finite number >= 0")
    # also with --width (the file is malformed whatever replaces its widths)
    refused(["import", str(src), "-o", str(out), "--width", "0.01"], capsys, str(out), r"offset 20: d_thickness")


def test_hair_default_thickness_zero_means_none_and_unused_bad_default_warns(tmp_path):
    pts, counts = strands([4, 4])
    src = ti.write_hair(tmp_path / "z.hair", pts, counts, d_thickness=0.0)
    result, notes = warned(src, tmp_path / "z.usda")
    assert "80 um" in result.widths and any("no hair widths in the file" in n for n in notes)
    thick = np.full(len(pts), 0.01, np.float32)
    src = ti.write_hair(tmp_path / "a.hair", pts, counts, thick, d_thickness=-1.0)
    result, notes = warned(src, tmp_path / "a.usda")
    assert result.widths == "per vertex, from the file"
    assert [n for n in notes if "d_thickness" in n] == [
        f"{src}: offset 20: d_thickness (the header's default thickness) = -1 is not a width; ignored "
        "(the thickness array gives the widths)"]


# -- 6. the Python API checks its arguments with ValueErrors --------------------------------------


@pytest.mark.parametrize("kwargs, pattern", [
    (dict(max_strands=2.5), r"max_strands / --max-strands = 2\.5: expected an integer >= 1"),
    (dict(max_strands=0), r"max_strands / --max-strands = 0: expected an integer >= 1"),
    (dict(max_strands="3"), r"max_strands / --max-strands = '3'"),
    (dict(every=True), r"every / --every = True: expected an integer >= 1"),
    (dict(every=2.0), r"every / --every = 2\.0"),
    (dict(segments=-1), r"segments / --segments = -1"),
    (dict(width="0.1"), r"width / --width = '0\.1': expected a finite number > 0"),
    (dict(width=True), r"width / --width = True"),
    (dict(width=math.nan), r"width / --width = nan"),
    (dict(width=-1.0), r"width / --width = -1\.0"),
    (dict(head_friction="0.2"), r"head_friction / --head-friction = '0\.2'"),
    (dict(units=True), r"--units True"),
    (dict(up_axis=1), r"--up-axis 1"),
    (dict(drop_nonfinite="yes"), r"drop_nonfinite = 'yes': expected True or False"),
])
def test_api_arguments_raise_value_errors(tmp_path, kwargs, pattern):
    src = ti.write_strand_list(tmp_path / "g.data", *strands([3, 3, 3]))
    out = tmp_path / "o.usda"
    with pytest.raises(ValueError, match=pattern) as info:
        import_groom(src, out, **kwargs)
    assert isinstance(info.value, UserError)  # the command's one line and exit status 2
    assert "\n" not in str(info.value)
    assert not out.exists()


def test_api_accepts_numpy_integers_and_plain_values(tmp_path):
    src = ti.write_strand_list(tmp_path / "g.data", *strands([3, 3, 3]))
    result, _ = warned(src, tmp_path / "o.usda", max_strands=np.int64(2), every=1, segments=np.int32(4),
                       width=np.float32(0.001), units=0.01, drop_nonfinite=np.bool_(False))
    assert result.strands == 2 and result.points == 10


def test_cli_bad_counts_one_line(tmp_path, capsys):
    src = ti.write_strand_list(tmp_path / "g.data", *strands([3, 3]))
    out = tmp_path / "o.usda"
    for extra, pattern in ((["--max-strands", "0"], r"--max-strands = 0: expected an integer >= 1"),
                           (["--width", "nan"], r"--width = nan: expected a finite number > 0"),
                           (["--every", "0"], r"--every = 0: expected an integer >= 1")):
        refused(["import", str(src), "-o", str(out), *extra], capsys, str(out), pattern)



def test_an_output_that_cannot_be_written_is_one_line(tmp_path, capsys):
    """A folder the process cannot write into (read-only /proc, even for root) and a 'folder' that
    is a file: one line each, exit 2, no traceback."""
    src = ascii_ply(tmp_path, "ok.ply")
    refused(["import", str(src), "-o", "/proc/x.usda"], capsys, "/proc/x.usda", r"/proc/x\.usda: cannot write: ")
    (tmp_path / "afile").write_text("not a folder")
    out = tmp_path / "afile" / "x.usda"
    code, _, err = ti.run_cli(["import", str(src), "-o", str(out)], capsys)
    assert code == 2 and err.strip().splitlines() == [f"dftl-warp: error: {out}: folder {tmp_path / 'afile'} "
                                                      "is a file, not a folder"], err


def test_ply_strand_ids_that_resume_after_other_strands_are_refused(tmp_path, capsys):
    """Strands delimited by a vertex strand_id are runs of one id; an id that comes back after
    another strand's vertices would have been split into two strands without a word."""
    head = ["ply", "format ascii 1.0", "element vertex 6", "property float x", "property float y",
            "property float z", "property int strand_id", "end_header"]
    src = tmp_path / "split.ply"
    src.write_text("\n".join(head + ["0 0 0 0", "0 -1 0 0", "1 0 0 1", "1 -1 0 1", "0 -2 0 0", "0 -3 0 0"]) + "\n")
    out = tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out)], capsys, str(out),
            r"split\.ply: strand_id 0 is not contiguous: its vertices resume at vertex 4")
    ok = tmp_path / "runs.ply"
    ok.write_text("\n".join(head + ["0 0 0 0", "0 -1 0 0", "1 0 0 1", "1 -1 0 1", "0 -2 0 2", "0 -3 0 2"]) + "\n")
    assert list(read_groom(ok).counts) == [2, 2, 2]


# -- 6. OBJ head meshes: what is skipped is one warning with counts; anything else names its line --

SQUARE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def test_obj_head_skips_texture_normals_materials_groups_with_one_warning(tmp_path, capsys):
    src, obj = head_files(tmp_path)
    obj.write_text("# exported\nmtllib head.mtl\no Head\ng scalp skin\n"
                   "v 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 1 1 0 1 0 0\nv 0 1 0 0.5 0.5 0.5\n"
                   "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nusemtl skin\ns 1\n"
                   "f 1/1/1 2/2/1 3/3/1   # v/vt/vn\nf -4//1 -2//-1 \\\n  -1//1\nf 1/1 3/3 2/-1\ns off\nl 1 2\n")
    out = tmp_path / "o.usda"
    code, _, err = ti.run_cli(["import", str(src), "-o", str(out), "--head", str(obj)], capsys)
    assert code == 0, err
    lines = [ln for ln in err.splitlines() if str(obj) in ln]
    assert lines == [f"dftl-warp: warning: {obj}: ignored what a collider does not use: 1 mtllib, 1 o, 1 g, "
                     "4 v extras (w or r g b), 3 vt, 1 vn, 1 usemtl, 2 s, 1 l"], err
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(out))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Groom/Head"))
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [3, 3, 3]
    assert list(mesh.GetFaceVertexIndicesAttr().Get()) == [0, 1, 2, 0, 2, 3, 0, 2, 1]
    np.testing.assert_array_equal(np.array(mesh.GetPointsAttr().Get()), [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    # a plain v/f file says nothing
    obj.write_text(SQUARE + "f 1 2 3 4\n")
    _, notes = warned(src, tmp_path / "p.usda", head=obj)
    assert not [n for n in notes if str(obj) in n]


@pytest.mark.parametrize("body, line, pattern", [
    (SQUARE + "f 1 2 3\nhair 1 2 3\n", 6, r"unknown OBJ statement 'hair 1 2 3'"),
    (SQUARE + "vertex 1 2 3\nf 1 2 3\n", 5, r"unknown OBJ statement 'vertex 1 2 3'"),
    ("v 0 0\n" + SQUARE + "f 1 2 3\n", 1, r"bad vertex 'v 0 0': expected x y z"),
    (SQUARE + "v 1 2 z\nf 1 2 3\n", 5, r"bad vertex 'v 1 2 z'"),
    (SQUARE + "f 1 2 x\n", 5, r"bad face index 'x'"),
    (SQUARE + "f 1 2\n", 5, r"a face needs at least 3 vertices"),
    (SQUARE + "f 1 2 5\n", 5, r"face vertex index 5 in '5' is out of range \(1\.\.4 or -4\.\.-1\)"),
    (SQUARE + "f 0 1 2\n", 5, r"face vertex index 0 in '0' is out of range"),
    (SQUARE + "f -5 1 2\n", 5, r"face vertex index -5 in '-5' is out of range"),
    (SQUARE + "vt 0 0\nf 1/2 2/1 3/1\n", 6, r"face vt index 2 in '1/2' is out of range \(1\.\.1 or -1\.\.-1\)"),
    (SQUARE + "f 1//1 2//1 3//1\n", 5, r"face vn index 1 in '1//1' is out of range \(none defined before this line\)"),
    (SQUARE + "f 1/ 2 3\n", 5, r"bad face vertex '1/': expected v, v/vt, v//vn or v/vt/vn"),
    (SQUARE + "f 1/1/1/1 2 3\n", 5, r"bad face vertex '1/1/1/1'"),
    (SQUARE + "f 1 2 3\ncstype bspline\n", 6, r"free-form geometry \('cstype'\) is not read: export the head as "
                                              r"polygons \(f\)"),
])
def test_obj_head_unknown_or_malformed_line_is_refused_naming_it(tmp_path, capsys, body, line, pattern):
    src, obj = head_files(tmp_path)
    obj.write_text(body)
    out = tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out), "--head", str(obj)], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(obj))}: line {line}: {pattern}")


# -- 7. TressFX: the header declares the whole file; bytes after its last array are an error -------


def tfx_bytes(strands_in_header, strands_written, per_strand=4, tail=b"", strand_uv=False):
    pts, _ = strands([per_strand] * strands_written)
    xyzw = np.concatenate([pts, np.ones((len(pts), 1), np.float32)], axis=1).astype("<f4").tobytes()
    uv_at = 160 + 16 * strands_in_header * per_strand if strand_uv else 0
    head = struct.pack("<f7I", 4.0, strands_in_header, per_strand, 160, uv_at, 0, 0, 0) + bytes(128)
    return head + xyzw + (bytes(8 * strands_in_header) if strand_uv else b"") + tail


def test_tfx_trailing_bytes_are_refused_naming_the_offset(tmp_path, capsys):
    # more strands in the file than numHairStrands says: the 3rd would have been dropped silently
    src = tmp_path / "more.tfx"
    src.write_bytes(tfx_bytes(2, 3))
    out = tmp_path / "o.usda"
    refused(["import", str(src), "-o", str(out)], capsys, str(out),
            rf"^dftl-warp: error: {re.escape(str(src))}: offset 288: 64 bytes after the last array the header "
            r"declares \(at offsetVertexPosition, which ends here\): the size of 1 more strand\(s\) of 4 vertices; "
            r"numHairStrands \(offset 4\) says 2$")
    # bytes that are no whole strand
    src.write_bytes(tfx_bytes(2, 2, tail=b"junk!"))
    with pytest.raises(UserError, match=r"offset 288: 5 bytes after the last array the header declares .*: the "
                                        r"header's counts and offsets do not add up"):
        read_groom(src)
    # declared strand UVs (as AMD's exporters write them, and the Ratboy sample ends) are part of the file
    src.write_bytes(tfx_bytes(2, 2, strand_uv=True))
    assert list(read_groom(src).counts) == [4, 4]
    src.write_bytes(tfx_bytes(2, 2, strand_uv=True, tail=bytes(16)))
    with pytest.raises(UserError, match=r"offset 304: 16 bytes after .* \(at offsetStrandUV, which ends here\)"):
        read_groom(src)
    # a declared array cut short
    src.write_bytes(tfx_bytes(2, 2, strand_uv=True)[:-4])
    with pytest.raises(UserError, match=r"offset 288: truncated: offsetStrandUV \(header offset 16\) declares "
                                        r"float2 strand UVs of 16 bytes, the file has 12 left"):
        read_groom(src)
