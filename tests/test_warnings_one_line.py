"""Python warnings raised anywhere in a command are one ``dftl-warp: warning: FILE: ...`` line each.

Before, only the per-frame collider update's warnings were routed (``simulate``): a collider
approximated by the clean start's first-frame update, numpy's RuntimeWarnings in the set-up, the
renderer or ``info``, came out as Python's two lines (``.../step.py:206: ColliderApproximationWarning:
/World/Grow: ...`` and a line of source; ``.../renderer.py:212: RuntimeWarning: overflow encountered
in cast``), naming no file, in no Summary and no batch job's warnings. Now each is one line naming
the input (and the prim where the warning names it), once, kept where the command keeps its
warnings (simulate's Summary, a batch job's warnings, info's description).
"""

from __future__ import annotations

import warnings

import numpy as np
from pxr import Sdf, UsdGeom, UsdPhysics, Vt
from test_features import box_mesh
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp.errors import WarningRoute

#: what a collider approximated at the clean start says (the prim, then how)
MOVING = "/World/Grow: its points move up to"


def field_box(stage, path, at: dict) -> None:
    """A box mesh collider 8 cm across with a signed distance field, its points time-sampled:
    ``at[time] = (scale, x shift)``."""
    points, faces = box_mesh((0.04, 0.04, 0.04))
    mesh = UsdGeom.Mesh.Define(stage, path)
    for time, (scale, shift) in at.items():
        moved = points * scale + np.array([shift, 0.0, 0.0])
        mesh.CreatePointsAttr().Set(Vt.Vec3fArray.FromNumpy(moved.astype(np.float32)), time)
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(faces)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in faces.reshape(-1)]))
    UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
    mesh.GetPrim().CreateAttribute("dftl:collisionSdf", Sdf.ValueTypeNames.Bool, custom=True).Set(True)


def _growing_mesh_stage(path):
    """Hair above a mesh collider with a signed distance field whose points jump 40x between the
    stage's start time 0.5 (where the scene is read) and frame 1 (the first frame simulated): the
    clean start's first-frame collider update moves it past its depth band, which is warned about."""
    stage = new_stage(path, start=0.5, end=3)
    add_curves(stage, "/World/Hair", chain(6, 0.02, direction=(0.0, -1.0, 0.0), origin=(0.0, 0.5, 0.0)), [6])
    field_box(stage, "/World/Grow", {0.5: (1.0, 0.0), 1: (41.0, 0.0), 3: (41.0, 0.0)})
    stage.Save()
    return str(path)


def _no_raw_warning(err: str) -> None:
    for raw in ("UserWarning", "RuntimeWarning:", "ApproximationWarning", ".py:", "Warp "):
        assert raw not in err, err


def test_a_collider_approximated_by_the_clean_start_is_one_line_before_the_run(tmp_path, capsys):
    from dftl_warp.simulation.simulate import simulate_usd

    path = _growing_mesh_stage(tmp_path / "grow.usda")
    assert cli.main(["simulate", path, "-o", str(tmp_path / "o.usdc"), "--solver", "dftl", "--device", "cpu"]) == 0
    err = capsys.readouterr().err
    _no_raw_warning(err)
    lines = err.splitlines()
    assert all(line.startswith("dftl-warp: ") for line in lines), lines
    said = [k for k, line in enumerate(lines) if line.startswith(f"dftl-warp: warning: {path}: {MOVING} ")]
    device = [k for k, line in enumerate(lines) if line.startswith("dftl-warp: device")]
    assert len(said) == 1 and said[0] < device[0], lines   # with the set-up's warnings, before the frames
    assert cli.main(["simulate", path, "-o", str(tmp_path / "q.usdc"), "--solver", "dftl", "--device", "cpu",
                     "-q"]) == 0
    quiet = capsys.readouterr().err
    _no_raw_warning(quiet)
    assert [line for line in quiet.splitlines() if MOVING in line] == [lines[said[0]]], quiet
    summary = simulate_usd(path, str(tmp_path / "s.usdc"), solver="dftl", device="cpu")
    assert [w for w in summary.warnings if MOVING in w] == [lines[said[0]][len("dftl-warp: warning: "):]], summary
    assert not any(MOVING in w for w in summary.run_warnings), summary


def test_a_batch_job_keeps_the_clean_start_s_collider_warning(tmp_path, capfd):
    from dftl_warp.batch.checkpoint import run_job
    from dftl_warp.batch.jobs import Job

    path = _growing_mesh_stage(tmp_path / "grow.usda")
    result = run_job(Job(index=1, name="grow", input=path, output=str(tmp_path / "j.usdc"),
                         options={"solver": "dftl"}), "cpu")
    assert result.status == "done", result.error
    assert sum(w.startswith(f"{path}: {MOVING} ") for w in result.warnings) == 1, result.warnings
    _no_raw_warning(capfd.readouterr().err)


def _hair_stage(path):
    stage = new_stage(path, start=1, end=1)
    # widths: curves without them are drawn at a default width with a warning (tests/test_render_audit.py)
    add_curves(stage, "/World/Hair", chain(4, 0.05, direction=(0.0, -1.0, 0.0)), [4], widths=0.005, bending=None)
    stage.Save()
    return str(path)


def test_a_render_time_numpy_warning_is_one_line_naming_the_stage(tmp_path, capfd, monkeypatch):
    """A numpy warning raised while the render reads its scene (here an overflowing cast added to the
    reader: a Sphere of radius 1e300, which raised it before, is now refused,
    tests/test_render_gprim_sizes.py) is one line naming the stage, not numpy's two."""
    from dftl_warp.render import usd_scene

    read = usd_scene.read_render_scene

    def overflowing(*args, **kwargs):
        np.float32(np.float64(1e300))   # numpy: "overflow encountered in cast"
        return read(*args, **kwargs)

    monkeypatch.setattr(usd_scene, "read_render_scene", overflowing)
    path = _hair_stage(tmp_path / "hair.usda")
    assert cli.main(["render", path, "-o", str(tmp_path / "hair.png"), "--device", "cpu", "--resolution", "32x18",
                     "--spp", "1", "-q"]) == 0
    err = capfd.readouterr().err
    _no_raw_warning(err)
    assert err.splitlines() == [f"dftl-warp: warning: {path}: overflow encountered in cast (RuntimeWarning)"], err


def test_info_refuses_a_collider_beyond_float32_in_one_line(tmp_path, capfd):
    """A sphere collider 1e300 units away: info's float32 collider tables overflowed (a numpy
    warning kept in its description, exit 0). The reader now refuses the position in one line."""
    from test_usd_features import sphere_collider

    path = tmp_path / "far.usda"
    stage = new_stage(path, start=1, end=3)
    add_curves(stage, "/World/Hair", chain(4, 0.05, direction=(0.0, -1.0, 0.0)), [4])
    sphere_collider(stage, "/World/Ball", 0.05, translate=(1e300, 0.0, 0.0))
    stage.Save()
    for extra in ([], ["--json"]):
        assert cli.main(["info", str(path), *extra]) == 2
        out, err = capfd.readouterr()
        assert out == "" and err.splitlines() == [
            f"dftl-warp: error: {path}: /World/Ball: translate = (1e+300, 0, 0) (its position in world space) does "
            f"not fit float32 (at most 3.403e+38): is the unit right?"], (out, err)


def test_the_route_names_the_file_folds_lines_and_takes_warp_s_warnings():
    import warp as wp

    said = []
    with WarningRoute(said.append, where="in.usda") as route:
        warnings.warn("/World/Ball: two\n   lines")
        warnings.warn("in.usda: names its file")
        np.float32(np.float64(1e300))
        wp.get_logger().warning("a Warp warning")
        route.where = "other.usda"
        warnings.warn("after")
    assert said == ["in.usda: /World/Ball: two lines", "in.usda: names its file",
                    "in.usda: overflow encountered in cast (RuntimeWarning)", "in.usda: Warp: a Warp warning",
                    "other.usda: after"], said
    assert type(wp.get_logger()).__name__ != "_WarpWarnings"   # Warp's own logger back


def test_the_route_holds_what_comes_before_it_knows_where_and_keeps_it_once():
    notes = ["in.usda: seen"]
    with WarningRoute(where="in.usda") as route:
        warnings.warn("early")
        warnings.warn("seen")
        route.keep_in(notes)
        warnings.warn("early")
        warnings.warn("late")
    assert notes == ["in.usda: seen", "in.usda: early", "in.usda: late"], notes
