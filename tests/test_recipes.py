"""The four "where to add" recipes of docs/architecture.md, each demonstrated end to end.

Each test copies ``dftl_warp/`` and ``kernels/`` (as ``dftl_warp/kernels``) into a temporary
folder, adds a toy of its kind there by writing or editing *only* the files its recipe names
(the toys are in ``tests/recipes/``), checks that exactly those files changed, and runs the toy in
a subprocess that imports the copy (``PYTHONPATH``): a toy solver, a toy output format, a toy
collider shape and a toy command.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TOYS = Path(__file__).resolve().parent / "recipes"

#: recipe -> the files (repository paths) a new thing of that kind touches
RECIPES = {
    "solver": {"dftl_warp/solvers/toy.py", "kernels/solvers/toy.py", "dftl_warp/solvers/__init__.py"},
    "writer": {"dftl_warp/output/npz.py", "dftl_warp/output/__init__.py"},
    "collider": {"dftl_warp/features/colliders/cylinder.py", "kernels/features/cylinder.py",
                 "dftl_warp/features/colliders/__init__.py"},
    "command": {"dftl_warp/commands/toy.py", "dftl_warp/cli.py"},
}

STAGE = """#usda 1.0
(
    defaultPrim = "World"
    startTimeCode = 1
    endTimeCode = {end}
    timeCodesPerSecond = 24
    upAxis = "Y"
    metersPerUnit = 1
)

def Xform "World"
{{
    def BasisCurves "Hair"
    {{
        uniform token type = "linear"
        int[] curveVertexCounts = [6, 6]
        point3f[] points = [(0, 1, 0), (0.08, 1, 0), (0.16, 1, 0), (0.24, 1, 0), (0.32, 1, 0), (0.4, 1, 0),
                            (0, 1, 0.05), (0.08, 1, 0.05), (0.16, 1, 0.05), (0.24, 1, 0.05), (0.32, 1, 0.05), (0.4, 1, 0.05)]
        float[] widths = [0.004] (interpolation = "constant")
        custom bool dftl:bending = false
    }}
{extra}
}}
"""

CYLINDER_PRIM = """
    def Cylinder "Post" (
        prepend apiSchemas = ["PhysicsCollisionAPI"]
    )
    {
        double radius = 0.06
        double height = 1
        uniform token axis = "Z"
        double3 xformOp:translate = (0.22, 0.78, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
"""


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _repository_path(root: Path, path: Path) -> str:
    """``path`` in the copy as a repository path (``dftl_warp/kernels/x.py`` -> ``kernels/x.py``)."""
    relative = path.relative_to(root).as_posix()
    return relative.removeprefix("dftl_warp/") if relative.startswith("dftl_warp/kernels/") else relative


def _in_copy(root: Path, repository_path: str) -> Path:
    if repository_path.startswith("kernels/"):
        return root / "dftl_warp" / repository_path
    return root / repository_path


def _snapshot(root: Path) -> dict:
    return {_repository_path(root, p): _digest(p) for p in root.rglob("*")
            if p.is_file() and "__pycache__" not in p.parts}


@pytest.fixture
def house(tmp_path):
    """A copy of the package in ``tmp_path/house`` and its files' digests before the recipe."""
    root = tmp_path / "house"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / "dftl_warp", root / "dftl_warp", ignore=ignore)
    shutil.copytree(ROOT / "kernels", root / "dftl_warp" / "kernels", ignore=ignore)
    return root, _snapshot(root)


def _changed(root: Path, before: dict) -> set:
    after = _snapshot(root)
    return {k for k in before.keys() | after.keys() if before.get(k) != after.get(k)}


def _add_toy(root: Path, toy: str) -> None:
    """Write ``tests/recipes/<toy>`` to the path its first line names."""
    first, body = (TOYS / toy).read_text().split("\n", 1)
    target = _in_copy(root, first.lstrip("# ").strip())
    assert not target.exists(), target
    target.write_text(body)


def _edit(root: Path, relative: str, old: str, new: str) -> None:
    path = _in_copy(root, relative)
    text = path.read_text()
    assert text.count(old) == 1, (relative, old)
    path.write_text(text.replace(old, new))


def _run(root: Path, args: list[str], cwd: Path) -> str:
    env = {**os.environ, "PYTHONPATH": str(root), "DFTL_WARP_DEVICE": "cpu"}
    done = subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def _python(root: Path, code: str, cwd: Path) -> str:
    prelude = (f"import dftl_warp, pathlib; assert pathlib.Path(dftl_warp.__file__).is_relative_to({str(root)!r}), "
               "dftl_warp.__file__\n")
    return _run(root, ["-c", prelude + textwrap.dedent(code)], cwd)


def test_recipe_solver(house, tmp_path):
    root, before = house
    _add_toy(root, "toy_solver.py")
    _add_toy(root, "toy_solver_kernel.py")
    _edit(root, "dftl_warp/solvers/__init__.py", "from . import dftl, pbd, reference", "from . import dftl, pbd, reference, toy")
    assert _changed(root, before) == RECIPES["solver"]

    out = _python(root, """
        import numpy as np
        from dftl_warp import Model, make_solver
        points = np.array([[0.0, 1.0, 0.0], [0.1, 1.0, 0.0], [0.2, 1.0, 0.0]])
        model = Model.from_strands(points, np.array([3]), device="cpu")
        solver = make_solver(model, "toy")
        state, control = solver.state(), model.control()
        solver.advance(state, control, 1.0 / 240.0, 24)
        x = model.points_from_device(state.positions.numpy())
        print(type(solver).__name__, float(np.linalg.norm(x[1] - x[0])), float(x[2, 1]))
    """, tmp_path)
    name, segment, tip_y = out.splitlines()[-1].split()
    assert name == "ToySolver" and abs(float(segment) - 0.1) < 1e-4 and float(tip_y) < 0.95

    stage = tmp_path / "hair.usda"
    stage.write_text(STAGE.format(end=4, extra=""))
    _run(root, ["-m", "dftl_warp", "simulate", str(stage), "-o", str(tmp_path / "out.usda"), "--solver", "toy",
                "--device", "cpu"], tmp_path)
    assert (tmp_path / "out.usda").is_file()


def test_recipe_writer(house, tmp_path):
    root, before = house
    _add_toy(root, "toy_writer.py")
    _edit(root, "dftl_warp/output/__init__.py", "register_writer(UsdWriter)  # .usdc, .usda, .usd\n",
          "register_writer(UsdWriter)  # .usdc, .usda, .usd\nfrom .npz import NpzWriter  # noqa: E402\n"
          "register_writer(NpzWriter)  # .npz\n")
    assert _changed(root, before) == RECIPES["writer"]

    stage = tmp_path / "hair.usda"
    stage.write_text(STAGE.format(end=5, extra=""))
    out = _python(root, f"""
        import json
        import numpy as np
        from dftl_warp import simulate_usd
        summary = simulate_usd({str(stage)!r}, {str(tmp_path / "out.npz")!r}, device="cpu")
        with np.load({str(tmp_path / "out.npz")!r}) as data:
            print(json.dumps({{"frames": summary.frames, "times": data["time_codes"].tolist(),
                              "shape": list(data["points0"].shape), "tip_y": float(data["points0"][-1, -1, 1])}}))
    """, tmp_path)
    result = json.loads(out.splitlines()[-1])
    assert result["frames"] == 5 and result["times"] == [1.0, 2.0, 3.0, 4.0, 5.0]
    assert result["shape"] == [5, 12, 3] and result["tip_y"] < 1.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hair.usda", "house", "out.npz"]  # no partial left


def test_recipe_collider(house, tmp_path):
    root, before = house
    _add_toy(root, "toy_collider.py")
    _add_toy(root, "toy_collider_kernel.py")
    _edit(root, "dftl_warp/features/colliders/__init__.py", "from .analytic import Box, Capsule, Sphere\n",
          "from .analytic import Box, Capsule, Sphere\nfrom .cylinder import Cylinder\n")
    _edit(root, "dftl_warp/features/colliders/__init__.py", "(Sphere, Capsule, Box, TriangleMesh)",
          "(Sphere, Capsule, Box, TriangleMesh, Cylinder)")
    assert _changed(root, before) == RECIPES["collider"]

    stage = tmp_path / "hair.usda"
    stage.write_text(STAGE.format(end=16, extra=CYLINDER_PRIM))
    out = _python(root, f"""
        import json
        import numpy as np
        from pxr import Usd, UsdGeom
        from dftl_warp import simulate_usd
        summary = simulate_usd({str(stage)!r}, {str(tmp_path / "out.usdc")!r}, device="cpu", substeps=8)
        stage = Usd.Stage.Open({str(tmp_path / "out.usdc")!r})
        points = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hair")).GetPointsAttr()
        gaps = []
        for t in range(1, 17):
            q = np.array(points.Get(t), dtype=np.float64) - [0.22, 0.78, 0.0]
            gaps.append(float((np.hypot(q[:, 0], q[:, 1]) - 0.06).min()))
        print(json.dumps({{"colliders": summary.colliders, "features": summary.groups[0]["features"],
                          "warnings": summary.warnings, "gaps": gaps}}))
    """, tmp_path)
    result = json.loads(out.splitlines()[-1])
    assert result["colliders"] == 1 and "cylinders" in result["features"], result
    assert not result["warnings"], result["warnings"]
    # the hair falls onto the cylinder (a particle within 5 mm of its surface) and stays outside
    # (particle radius 2 mm, a little slack for the last substep's restore)
    assert min(result["gaps"]) < 0.005, result["gaps"]
    assert min(result["gaps"]) > -1e-3, result["gaps"]


def test_recipe_collider_needs_its_registration(tmp_path):
    """Without the toy, the same stage's Cylinder is ignored with a warning (the reader reads only
    the collision prim types a registered shape asked for)."""
    stage = tmp_path / "hair.usda"
    stage.write_text(STAGE.format(end=2, extra=CYLINDER_PRIM))
    from dftl_warp.usd.read import read_scene

    scene = read_scene(str(stage))
    assert not scene.colliders and any("Cylinder is not supported" in w for w in scene.warnings)


def test_recipe_command(house, tmp_path):
    root, before = house
    _add_toy(root, "toy_command.py")
    _edit(root, "dftl_warp/cli.py", '"devices", "import_groom")', '"devices", "import_groom", "toy")')
    assert _changed(root, before) == RECIPES["command"]

    out = _run(root, ["-m", "dftl_warp", "toy", "--name", "recipe"], tmp_path)
    assert out.startswith("hello recipe from dftl-warp ")
    assert "toy" in _run(root, ["-m", "dftl_warp", "--help"], tmp_path)
