"""``dftl-warp import``: readers of research hair formats and the USD groom they write (CPU only).

Every test writes its own small synthetic files (a helix groom with known coordinates)."""

from __future__ import annotations

import importlib
import os
import struct
import subprocess
import sys
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dftl_warp.errors import UserError
from dftl_warp.importers import GroomImportWarning, read_groom, readers
from dftl_warp.importers.convert import import_groom

# the "no widths in the file" notes are expected here; tests that check warnings use pytest.warns
pytestmark = pytest.mark.filterwarnings("ignore::dftl_warp.importers.GroomImportWarning")


def usd_reader():
    """The simulator's USD reader, wherever the package layout puts it."""
    for name in ("dftl_warp.usd.read", "dftl_warp.usd_read"):
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError:
            continue
        if hasattr(module, "read_scene"):
            return module
    pytest.skip("no dftl_warp USD reader module found")


# -- synthetic grooms and writers ------------------------------------------------------------


def helix_groom(counts=(5, 8, 3, 6)):
    """Concatenated points of helical strands (vertex counts ``counts``) and their widths."""
    pts, widths = [], []
    for k, n in enumerate(counts):
        t = np.linspace(0.0, 2.0, n)
        pts.append(np.stack([np.cos(3 * t) + 3 * k, np.sin(3 * t), 10.0 - 2.0 * t], axis=1))
        widths.append(0.01 + 0.001 * np.arange(n) + k * 0.0001)
    return np.concatenate(pts).astype(np.float32), np.asarray(counts, np.int64), np.concatenate(widths).astype(np.float32)


def write_hair(path, points, counts, thickness=None, *, d_thickness=0.0, segments_array=True):
    arrays = 2 | (1 if segments_array else 0) | (4 if thickness is not None else 0)
    d_segments = 0 if segments_array else int(counts[0]) - 1
    head = struct.pack("<4s4I5f", b"HAIR", len(counts), len(points), arrays, d_segments, d_thickness, 0.0, 1, 1, 1)
    head += b"synthetic".ljust(88, b"\0")
    body = b""
    if segments_array:
        body += (np.asarray(counts) - 1).astype("<u2").tobytes()
    body += np.asarray(points, "<f4").tobytes()
    if thickness is not None:
        body += np.asarray(thickness, "<f4").tobytes()
    path.write_bytes(head + body)
    return path


def write_strand_list(path, points, counts, extra_floats=0):
    out = [struct.pack("<i", len(counts))]
    start = 0
    for n in counts:
        out.append(struct.pack("<i", int(n)))
        p = np.asarray(points[start:start + n], "<f4")
        if extra_floats:
            p = np.concatenate([p, np.zeros((n, extra_floats), "<f4")], axis=1)
        out.append(p.tobytes())
        start += n
    path.write_bytes(b"".join(out))
    return path


def write_tfx(path, points, per_strand, version=4.0):
    n = len(points) // per_strand
    head = struct.pack("<f7I", version, n, per_strand, 160, 0, 0, 0, 0) + bytes(128)
    w = np.ones((len(points), 1), "<f4")
    w[::per_strand] = 0.0
    path.write_bytes(head + np.concatenate([np.asarray(points, "<f4"), w], axis=1).tobytes())
    return path


def write_ply(path, points, counts, widths=None, *, binary=True, delimit="strand"):
    n = len(points)
    lines = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0", "comment synthetic",
             f"element vertex {n}", "property float x", "property float y", "property float z"]
    if widths is not None:
        lines.append("property float thickness")
    if delimit == "strand_id":
        lines.append("property int strand_id")
    if delimit == "strand":
        lines += [f"element strand {len(counts)}", "property ushort nsegs"]
    edges = []
    if delimit == "edge":
        start = 0
        for c in counts:
            edges += [(start + j, start + j + 1) for j in range(c - 1)]
            start += c
        lines += [f"element edge {len(edges)}", "property int vertex1", "property int vertex2"]
    lines.append("end_header")
    header = ("\n".join(lines) + "\n").encode()
    ids = np.repeat(np.arange(len(counts)), counts)
    cols = [np.asarray(points, np.float32)]
    if widths is not None:
        cols.append(np.asarray(widths, np.float32)[:, None])
    if binary:
        fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")] + ([("t", "<f4")] if widths is not None else []) \
            + ([("id", "<i4")] if delimit == "strand_id" else [])
        rows = np.zeros(n, dtype=fields)
        rows["x"], rows["y"], rows["z"] = points[:, 0], points[:, 1], points[:, 2]
        if widths is not None:
            rows["t"] = widths
        if delimit == "strand_id":
            rows["id"] = ids
        body = rows.tobytes()
        if delimit == "strand":
            body += (np.asarray(counts) - 1).astype("<u2").tobytes()
        if delimit == "edge":
            body += np.asarray(edges, "<i4").tobytes()
    else:
        out = []
        for i in range(n):
            row = [repr(float(v)) for v in np.asarray(points[i], np.float32)]
            if widths is not None:
                row.append(repr(float(np.float32(widths[i]))))
            if delimit == "strand_id":
                row.append(str(ids[i]))
            out.append(" ".join(row))
        if delimit == "strand":
            out += [str(c - 1) for c in counts]
        if delimit == "edge":
            out += [f"{a} {b}" for a, b in edges]
        body = ("\n".join(out) + "\n").encode()
    path.write_bytes(header + body)
    return path


def write_all(tmp_path):
    """One valid file per format, with the helix groom."""
    pts, counts, w = helix_groom()
    return {
        "hair": write_hair(tmp_path / "g.hair", pts, counts, w),
        "data": write_strand_list(tmp_path / "g.data", pts, counts),
        "ct2hair": write_strand_list(tmp_path / "g.bin", pts, counts, extra_floats=4),
        "tfx": write_tfx(tmp_path / "g.tfx", *helix_groom((4, 4, 4))[:1], 4),
        "ply": write_ply(tmp_path / "g.ply", pts, counts, w),
    }


def run_cli(argv, capsys):
    from dftl_warp.cli import main

    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def check_topology(curves):
    """BasisCurves has no ValidateTopology (only Mesh does): the equivalent checks of its sizes."""
    from pxr import Usd, UsdGeom

    counts = np.array(curves.GetCurveVertexCountsAttr().Get())
    points = curves.GetPointsAttr().Get()
    assert np.all(counts >= 2)
    assert curves.ComputeVertexDataSize(Usd.TimeCode.Default()) == len(points) == counts.sum()
    assert sum(curves.ComputeSegmentCounts(Usd.TimeCode.Default())) == int((counts - 1).sum())
    n = len(curves.GetWidthsAttr().Get())
    if curves.GetWidthsInterpolation() == UsdGeom.Tokens.vertex:
        assert n == curves.ComputeVertexDataSize(Usd.TimeCode.Default())
    else:
        assert curves.GetWidthsInterpolation() == UsdGeom.Tokens.constant and n == 1


def open_curves(path):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    assert stage, path
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Groom/Hair"))
    return stage, curves


# -- round trips -----------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["hair", "data", "ct2hair", "ply-binary", "ply-ascii", "ply-edge", "ply-id", "tfx"])
def test_round_trip(tmp_path, fmt):
    from pxr import UsdGeom

    pts, counts, w = helix_groom()
    has_widths = fmt in ("hair", "ply-binary", "ply-ascii")
    if fmt == "hair":
        src = write_hair(tmp_path / "g.hair", pts, counts, w)
    elif fmt == "data":
        src = write_strand_list(tmp_path / "g.data", pts, counts)
    elif fmt == "ct2hair":
        src = write_strand_list(tmp_path / "g.bin", pts, counts, extra_floats=4)
    elif fmt.startswith("ply"):
        kind = {"ply-binary": "strand", "ply-ascii": "strand", "ply-edge": "edge", "ply-id": "strand_id"}[fmt]
        src = write_ply(tmp_path / "g.ply", pts, counts, w if has_widths else None,
                        binary=fmt != "ply-ascii", delimit=kind)
    else:
        pts, counts, _ = helix_groom((6, 6, 6))
        src = write_tfx(tmp_path / "g.tfx", pts, 6)
    out = tmp_path / "g.usda"
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        result = import_groom(src, out)
    assert result.strands == len(counts)
    stage, curves = open_curves(out)
    assert stage.GetDefaultPrim().GetPath() == "/Groom"
    assert stage.GetDefaultPrim().IsA(UsdGeom.Xform)
    np.testing.assert_array_equal(np.array(curves.GetCurveVertexCountsAttr().Get()), counts)
    np.testing.assert_array_equal(np.array(curves.GetPointsAttr().Get(), dtype=np.float32), pts)
    assert curves.GetTypeAttr().Get() == "linear" and curves.GetWrapAttr().Get() == "nonperiodic"
    widths = np.array(curves.GetWidthsAttr().Get(), dtype=np.float32)
    if has_widths:
        assert curves.GetWidthsInterpolation() == "vertex"
        np.testing.assert_array_equal(widths, w)
    else:
        assert curves.GetWidthsInterpolation() == "constant" and widths.size == 1
        reader = readers()[result.format]
        assert widths[0] == pytest.approx(80e-6 / reader.meters_per_unit, rel=1e-6)
    check_topology(curves)
    assert stage.GetStartTimeCode() == 1 and stage.GetEndTimeCode() == 48 and stage.GetTimeCodesPerSecond() == 24
    extent = np.array(curves.GetExtentAttr().Get())
    assert np.all(extent[0] <= pts.min(axis=0)) and np.all(extent[1] >= pts.max(axis=0))


def test_simulator_reads_the_groom_and_head(tmp_path, capsys):
    from pxr import Usd, UsdGeom, UsdPhysics

    src = write_all(tmp_path)["ct2hair"]
    obj = tmp_path / "head.obj"
    obj.write_text("# cube\n" + "".join(f"v {x} {y} {z}\n" for x in (-1, 1) for y in (-1, 1) for z in (-1, 1))
                   + "vt 0 0\nf 1/1 2/1 4/1 3/1\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf -7 -3 -1 -5\n")
    out = tmp_path / "g.usdc"
    code, stdout, err = run_cli(["import", str(src), "-o", str(out), "--head", str(obj), "--head-friction", "0.2"],
                                capsys)
    assert code == 0, err
    assert str(out) in stdout
    stage = Usd.Stage.Open(str(out))
    head = stage.GetPrimAtPath("/Groom/Head")
    assert head.IsA(UsdGeom.Mesh) and head.HasAPI(UsdPhysics.CollisionAPI)
    mesh = UsdGeom.Mesh(head)
    ok, why = UsdGeom.Mesh.ValidateTopology(mesh.GetFaceVertexIndicesAttr().Get(),
                                            mesh.GetFaceVertexCountsAttr().Get(), len(mesh.GetPointsAttr().Get()))
    assert ok, why
    scene = usd_reader().read_scene(str(out))
    assert sum(c.num_strands for c in scene.curves) == 4
    assert [c.kind for c in scene.colliders] == ["mesh"]
    assert scene.colliders[0].friction == pytest.approx(0.2)
    assert scene.stage.meters_per_unit == pytest.approx(0.001)


def test_head_mesh_ply(tmp_path):
    from pxr import Usd, UsdGeom

    src = write_all(tmp_path)["data"]
    ply = tmp_path / "head.ply"
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
              "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n").encode()
    body = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "<f4").tobytes()
    body += bytes([3]) + np.array([0, 1, 2], "<i4").tobytes() + bytes([4]) + np.array([0, 1, 2, 3], "<i4").tobytes()
    ply.write_bytes(header + body)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        import_groom(src, tmp_path / "g.usda", head=ply)
    stage = Usd.Stage.Open(str(tmp_path / "g.usda"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Groom/Head"))
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [3, 4]
    assert list(mesh.GetFaceVertexIndicesAttr().Get()) == [0, 1, 2, 0, 1, 2, 3]


# -- units, axes, widths, subsampling, resampling ---------------------------------------------


def test_units_and_up_axis(tmp_path):
    src = write_all(tmp_path)["data"]
    pts, counts, _ = helix_groom()
    for units, mpu in (("cm", 0.01), ("mm", 0.001), ("0.5", 0.5), (None, 1.0)):
        for axis in ("Y", "Z", None):
            out = tmp_path / f"g_{units}_{axis}.usda"
            with warnings.catch_warnings(record=True):
                warnings.simplefilter("always")
                import_groom(src, out, units=units, up_axis=axis)
            stage, curves = open_curves(out)
            from pxr import UsdGeom

            assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(mpu)
            assert UsdGeom.GetStageUpAxis(stage) == (axis or "Y")
            # points are written as read; the stage metadata carries the unit and axis
            np.testing.assert_array_equal(np.array(curves.GetPointsAttr().Get(), np.float32), pts)
            assert curves.GetWidthsAttr().Get()[0] == pytest.approx(80e-6 / mpu, rel=1e-6)
    # the simulator turns the unit into gravity in stage units
    scene = usd_reader().read_scene(str(tmp_path / "g_cm_Z.usda"))
    np.testing.assert_allclose(scene.gravity, [0, 0, -981.0])


def test_x_up_is_rotated_to_y_up(tmp_path):
    from pxr import UsdGeom

    pts = np.array([[0, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 2, 1]], np.float32)  # hanging along -X
    src = write_ply(tmp_path / "g.ply", pts, [2, 2])
    with pytest.warns(GroomImportWarning, match="rotated"):
        import_groom(src, tmp_path / "g.usda", up_axis="X")
    stage, curves = open_curves(tmp_path / "g.usda")
    assert UsdGeom.GetStageUpAxis(stage) == "Y"
    np.testing.assert_allclose(curves.GetPointsAttr().Get(), [[0, 0, 0], [0, -1, 0], [0, 0, 1], [-2, 0, 1]])


def test_defaults_per_format(tmp_path):
    assert readers()["hair"].up_axis == "Z"
    assert readers()["data"].meters_per_unit == 1.0
    assert readers()["ct2hair"].meters_per_unit == 0.001


def test_width_option_overrides(tmp_path):
    src = write_all(tmp_path)["hair"]
    import_groom(src, tmp_path / "g.usda", width=0.5)
    _, curves = open_curves(tmp_path / "g.usda")
    assert list(curves.GetWidthsAttr().Get()) == [0.5] and curves.GetWidthsInterpolation() == "constant"


def test_hair_default_thickness_and_segments(tmp_path):
    pts, counts, _ = helix_groom((4, 4, 4))
    src = write_hair(tmp_path / "d.hair", pts, counts, d_thickness=0.25, segments_array=False)
    import_groom(src, tmp_path / "g.usda")
    _, curves = open_curves(tmp_path / "g.usda")
    assert list(curves.GetCurveVertexCountsAttr().Get()) == [4, 4, 4]
    assert list(curves.GetWidthsAttr().Get()) == [0.25]


def test_single_vertex_strands_dropped_with_one_warning(tmp_path, capsys):
    pts, counts, _ = helix_groom((5, 1, 4, 1, 1, 3, 0))
    src = write_strand_list(tmp_path / "g.data", pts, counts)
    with pytest.warns(GroomImportWarning) as record:
        result = import_groom(src, tmp_path / "g.usda")
    drops = [str(w.message) for w in record if "fewer than 2 vertices" in str(w.message)]
    assert len(drops) == 1 and "dropped 4 of 7" in drops[0]
    assert result.strands == 3
    _, curves = open_curves(tmp_path / "g.usda")
    assert list(curves.GetCurveVertexCountsAttr().Get()) == [5, 4, 3]
    keep = np.repeat(np.array([1, 0, 1, 0, 0, 1, 0], bool), counts)
    np.testing.assert_array_equal(np.array(curves.GetPointsAttr().Get(), np.float32), pts[keep])
    # the CLI prints each warning once, on one line
    code, _, err = run_cli(["import", str(src), "-o", str(tmp_path / "h.usda")], capsys)
    assert code == 0 and err.count("fewer than 2 vertices") == 1


def test_subsample(tmp_path):
    pts, counts, _ = helix_groom(tuple(range(2, 22)))
    src = write_strand_list(tmp_path / "g.data", pts, counts)
    with pytest.warns(GroomImportWarning, match="kept 4 of 20"):
        import_groom(src, tmp_path / "a.usda", every=5)
    _, curves = open_curves(tmp_path / "a.usda")
    assert list(curves.GetCurveVertexCountsAttr().Get()) == [2, 7, 12, 17]
    with pytest.warns(GroomImportWarning, match="kept 3 of 20"):
        import_groom(src, tmp_path / "b.usda", every=2, max_strands=3)
    _, curves = open_curves(tmp_path / "b.usda")
    assert list(curves.GetCurveVertexCountsAttr().Get()) == [2, 10, 20]  # strands 0, 8, 18 of 0, 2, ..., 18


def test_resample_by_arc_length(tmp_path):
    # an L-shaped strand of length 3 and a straight one of length 1
    pts = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 0, 5], [0, 0, 6]], np.float32)
    src = write_ply(tmp_path / "g.ply", pts, [3, 2], widths=np.array([1, 1, 3, 2, 4], np.float32))
    import_groom(src, tmp_path / "g.usda", segments=3)
    _, curves = open_curves(tmp_path / "g.usda")
    assert list(curves.GetCurveVertexCountsAttr().Get()) == [4, 4]
    got = np.array(curves.GetPointsAttr().Get())
    np.testing.assert_allclose(got[:4], [[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 1, 0]], atol=1e-6)
    np.testing.assert_allclose(got[4:], [[0, 0, 5], [0, 0, 5 + 1 / 3], [0, 0, 5 + 2 / 3], [0, 0, 6]], atol=1e-6)
    np.testing.assert_allclose(curves.GetWidthsAttr().Get(), [1, 1, 1, 3, 2, 2 + 2 / 3, 2 + 4 / 3, 4], atol=1e-6)


def test_drop_nonfinite(tmp_path):
    pts, counts, _ = helix_groom()
    pts[6, 1] = np.nan
    src = write_strand_list(tmp_path / "g.bin", pts, counts, extra_floats=4)
    with pytest.raises(UserError, match=r"g\.bin: strand 1: point 1 .* not finite"):
        import_groom(src, tmp_path / "a.usda")
    with pytest.warns(GroomImportWarning, match="dropped 1 of 4 strands with NaN"):
        result = import_groom(src, tmp_path / "b.usda", drop_nonfinite=True)
    assert result.strands == 3


# -- malformed input: one line, exit 2, no output -----------------------------------------------


def malformed_cases(tmp_path):
    good = write_all(tmp_path)
    pts, counts, w = helix_groom()
    hair = good["hair"].read_bytes()
    data = good["data"].read_bytes()
    tfx = good["tfx"].read_bytes()
    ply = good["ply"].read_bytes()
    nan = pts.copy()
    nan[3, 0] = np.inf

    def put(name, content):
        p = tmp_path / name
        p.write_bytes(content)
        return p

    return {
        "hair truncated": (put("t.hair", hair[:-7]), r"offset \d+: truncated"),
        "hair header truncated": (put("h.hair", hair[:100]), r"offset 0: truncated"),
        "hair signature": (put("s.hair", b"HAIX" + hair[4:]), r"offset 0: signature"),
        "hair counts": (put("c.hair", hair[:8] + struct.pack("<I", 999) + hair[12:]), r"offset 128: .*point_count"),
        "hair no points": (put("p.hair", hair[:12] + struct.pack("<I", 1) + hair[16:]), r"offset 12: .*no points"),
        "hair nan": (write_hair(tmp_path / "n.hair", nan, counts, w), r"strand 0: point 3 .* not finite"),
        "data truncated": (put("t.data", data[:-1]), r"offset \d+: truncated: strand 3"),
        "data negative strands": (put("n.data", struct.pack("<i", -2) + data[4:]), r"offset 0: strand count -2"),
        "data negative vertices": (put("v.data", data[:4] + struct.pack("<i", -5) + data[8:]),
                                   r"offset 4: strand 0: vertex count -5"),
        "data trailing": (put("x.data", data + b"\0\0\0\0"), r"bytes after the last of 4 strands"),
        "data huge count": (put("h.data", struct.pack("<i", 2 ** 31 - 1) + data[4:]), r"offset 0: strand count"),
        "data empty": (put("e.data", b""), r"offset 0: truncated"),
        "data nan": (write_strand_list(tmp_path / "nan.data", nan, counts), r"strand 0: point 3"),
        "bin stride": (put("s.bin", data), r"offset \d+: "),
        "tfx truncated": (put("t.tfx", tfx[:-16]), r"offset 160: truncated"),
        "tfx version": (put("v.tfx", struct.pack("<f", float("nan")) + tfx[4:]), r"offset 0: version"),
        "tfx ascii": (put("a.tfx", b"version 2.0\nnumStrands 1\n"), r"offset 0: an ASCII TressFX"),
        "tfx one vertex": (put("o.tfx", tfx[:8] + struct.pack("<I", 1) + tfx[12:]), r"offset 8: numVerticesPerStrand"),
        "ply signature": (put("s.ply", b"plx" + ply[3:]), r"offset 0: signature"),
        "ply truncated": (put("t.ply", ply[:-3]), r"offset \d+: truncated: element 'strand'"),
        "ply counts": (put("c.ply", ply.replace(b"element strand 4", b"element strand 3")),
                       r"gives \d+ vertices for 3 strands"),
        "ply no strands": (put("n.ply", write_ply(tmp_path / "tmp.ply", pts, counts, delimit="none").read_bytes()),
                           r"cannot tell where strands start"),
        "ply ascii bad number": (put("b.ply", write_ply(tmp_path / "tmp2.ply", pts, counts, binary=False)
                                     .read_bytes().replace(b"\n4\n", b"\nfour\n", 1)), r"line \d+: "),
        "unknown extension": (put("g.xyz", data), r"unknown extension '.xyz'"),
        "missing file": (tmp_path / "absent.data", r"no such file"),
    }


def test_malformed_inputs_exit_2_with_one_line(tmp_path, capsys):
    cases = malformed_cases(tmp_path)
    for name, (src, pattern) in cases.items():
        out = tmp_path / "out" / "g.usda"
        out.parent.mkdir(exist_ok=True)
        code, stdout, err = run_cli(["import", str(src), "-o", str(out)], capsys)
        assert code == 2, (name, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1, (name, err)
        assert lines[0].startswith(f"dftl-warp: error: {src}: ") or "unknown extension" in lines[0], (name, lines)
        import re

        assert re.search(pattern, lines[0]), (name, lines[0])
        assert "Traceback" not in err
        assert not out.exists(), name
        assert os.listdir(out.parent) == [], (name, os.listdir(out.parent))  # no temporary files left


def test_bad_options_exit_2(tmp_path, capsys):
    src = write_all(tmp_path)["data"]
    for extra in (["--units", "furlongs"], ["--units", "-1"], ["--every", "0"], ["--segments", "0"],
                  ["--width", "0"], ["--head", str(tmp_path / "nohead.obj")], ["--format", "nope"]):
        argv = ["import", str(src), "-o", str(tmp_path / "o.usda")] + extra
        if extra[0] == "--format":
            with pytest.raises(SystemExit):  # argparse choices
                run_cli(argv, capsys)
            continue
        code, _, err = run_cli(argv, capsys)
        assert code == 2 and len(err.strip().splitlines()) == 1, (extra, err)
        assert not (tmp_path / "o.usda").exists()
    code, _, err = run_cli(["import", str(src), "-o", str(tmp_path / "o.txt")], capsys)
    assert code == 2 and "output must be" in err


def test_subprocess_has_no_traceback(tmp_path):
    src = tmp_path / "bad.hair"
    src.write_bytes(b"HAIR" + bytes(20))
    out = tmp_path / "g.usda"
    proc = subprocess.run([sys.executable, "-m", "dftl_warp", "import", str(src), "-o", str(out)],
                          capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONWARNINGS": "ignore"})
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().splitlines() == [f"dftl-warp: error: {src}: offset 0: truncated: the 128-byte HAIR "
                                                f"header needs 128 bytes, the file has 24 left (file size 24)"]
    assert not out.exists()


# -- fuzzing: every reader either succeeds or raises UserError ----------------------------------

FUZZ_FILES = {}


def fuzz_seed(name):
    if not FUZZ_FILES:
        import tempfile
        from pathlib import Path

        with tempfile.TemporaryDirectory() as d:
            for fmt, p in write_all(Path(d)).items():
                FUZZ_FILES[fmt] = (p.name, p.read_bytes())
            pts, counts, w = helix_groom()
            FUZZ_FILES["ply-ascii"] = ("a.ply", write_ply(Path(d) / "a.ply", pts, counts, w, binary=False).read_bytes())
    return FUZZ_FILES[name]


def read_or_user_error(name, data):
    reader = readers()["ply" if name == "ply-ascii" else name]
    try:
        groom = reader.read(data, f"fuzz.{name}")
    except UserError as exc:
        assert "\n" not in str(exc)
        return
    assert groom.points.shape == (int(groom.counts.sum()), 3)


FORMATS = ["hair", "data", "ct2hair", "tfx", "ply", "ply-ascii"]
FUZZ = settings(max_examples=int(os.environ.get("DFTL_FUZZ_EXAMPLES", "150")), deadline=None, suppress_health_check=[HealthCheck.too_slow])


@pytest.mark.parametrize("name", FORMATS)
@FUZZ
@given(data=st.binary(max_size=400))
def test_fuzz_random_bytes(name, data):
    read_or_user_error(name, data)


@pytest.mark.parametrize("name", FORMATS)
@FUZZ
@given(cut=st.integers(min_value=0, max_value=10_000), flips=st.lists(
    st.tuples(st.integers(min_value=0, max_value=10_000), st.integers(min_value=0, max_value=255)), max_size=4))
def test_fuzz_truncated_and_corrupted(name, cut, flips):
    _, good = fuzz_seed(name)
    data = bytearray(good[:cut % (len(good) + 1)])
    for at, value in flips:
        if data:
            data[at % len(data)] = value
    read_or_user_error(name, bytes(data))


@pytest.mark.parametrize("name", ["hair", "data", "ct2hair", "tfx", "ply"])
def test_read_groom_by_extension(tmp_path, name):
    src = write_all(tmp_path)[name]
    groom = read_groom(src)
    assert groom.format == name and groom.num_strands in (3, 4)
