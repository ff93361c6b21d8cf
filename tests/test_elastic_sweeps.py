"""On CUDA the elastic step runs its three sweeps (frames, elimination, back substitution) as three
kernels, each compiled with only the registers it needs (kernels/solvers/elastic.py: CUDA_PHASES).
They hand each other their results through global memory as the single kernel's sweeps do, so a
step of the three must equal a step of the one bit for bit, with every feature the step supports.
The CPU runs the single kernel; here the CPU runs the three, as a GPU would, and both are compared.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, UsdGeom, UsdPhysics
from usd_stages import add_curves, animated_xform, chain, new_stage, set_attr

import dftl_warp.solvers.elastic as solver_module
from dftl_warp.kernels.solvers.elastic import CUDA_PHASES
from dftl_warp.simulation.simulate import Simulation, SimulationOptions
from dftl_warp.usd.read import read_scene


def _stage(path, hair_hair: bool):
    """Curly 0.5 mm hair (in cm) under a moving, turning head, a ball some strands start inside, wind
    and drag, and hair-hair where asked."""
    stage = new_stage(path, meters_per_unit=0.01, start=1, end=8)
    world = stage.GetPrimAtPath("/World")
    set_attr(world, "dftl:wind", "Float3", Gf.Vec3f(30.0, 0.0, 0.0))
    if hair_hair:
        set_attr(world, "dftl:hairHair", "Bool", True)
    animated_xform(stage, "/World/Head", translate={1: (0, 100, 0), 8: (4, 100, 0)}, rotate_y={1: 0.0, 8: 40.0})
    ball = UsdGeom.Sphere.Define(stage, "/World/Head/Ball")
    ball.CreateRadiusAttr(2.0)
    UsdGeom.XformCommonAPI(ball).SetTranslate(Gf.Vec3d(2.0, -6.0, 0.5))
    UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    t = np.linspace(0.0, 4 * np.pi, 12)
    curl = np.c_[0.6 * np.cos(t) - 0.6, -0.8 * np.arange(12), 0.6 * np.sin(t)]
    pts = [curl + (k * 0.4, 0, 0) for k in range(6)] + [chain(9, 0.8, direction=(0.3, -1, 0.1), origin=(k, 0, 1))
                                                        for k in range(4)]
    curves = add_curves(stage, "/World/Head/Hair", np.concatenate(pts), [12] * 6 + [9] * 4, widths=0.05,
                        bending=None)
    set_attr(curves.GetPrim(), "dftl:drag", "Float", 1.5)
    stage.GetRootLayer().Save()
    return path


def _run(path, sweeps: bool, monkeypatch, **options):
    with monkeypatch.context() as patch:
        if sweeps:
            make = solver_module.elastic_step_kernels
            patch.setattr(solver_module, "elastic_step_kernels", lambda *a: make(*a[:-1], True))
        sim = Simulation(read_scene(str(path)), SimulationOptions(device="cpu", **options), 1)
        solver = sim.groups[0].solver
        assert len(solver._kernels) == (len(CUDA_PHASES) if sweeps else 1)
        frames = []
        for _ in range(5):
            sim.advance()
            frames.append([(p.copy(), v.copy()) for p, v in sim.samples()])
    return frames


@pytest.mark.parametrize("hair_hair,correction", [(False, "prior"), (True, "posterior")])
def test_three_sweep_kernels_equal_the_single_kernel(tmp_path, monkeypatch, hair_hair, correction):
    path = _stage(tmp_path / "hair.usda", hair_hair)
    want = _run(path, False, monkeypatch, correction=correction, arithmetic="float32")
    got = _run(path, True, monkeypatch, correction=correction, arithmetic="float32")
    # the hair swings against its head (local space, cm)
    assert max(float(np.abs(p - want[0][0][0]).max()) for p, _ in want[-1]) > 0.1
    for frame_got, frame_want in zip(got, want):
        for (p, v), (q, w) in zip(frame_got, frame_want):
            assert p.tobytes() == q.tobytes() and v.tobytes() == w.tobytes()


def test_the_kernels_loaded_before_a_graph_capture_are_listed_once():
    """``kernels()`` (what a CUDA graph capture loads first) named the featured step's first kernel
    twice: the features' list holds it, and the solver added its own."""
    import dftl_warp as dw
    from dftl_warp import features as F

    pts = np.stack([np.zeros(5), -np.arange(5) * 0.01, np.zeros(5)], 1)
    model = dw.Model.from_strands(pts, [5], widths=1e-4,
                                  features=[F.Colliders([F.Sphere(radius=0.01, position=(0.0, -0.1, 0.0))])])
    kernels = dw.make_solver(model, "elastic", radius=5e-5).kernels()
    assert len(kernels) == len(set(kernels)) >= 2
