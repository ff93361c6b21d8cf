"""The per-prim QC of a group whose device strands are not in the prims' order.

On CUDA the particle-major layout orders a group's strands along the Morton curve of their roots,
so the strands of two prims interleave on the device. The QC once mapped device strand ``s`` to the
prim of input strand ``s``: on the GPU a strand stuck inside a sphere was reported under the other
prim (``dftl:qc:maxPenetration`` 0 where the clean start named 41 hair radii), and the energies were
summed over the wrong strands. The CPU uses the strand-major layout (device order = input order),
so these tests put the CPU on the particle-major layout, as CUDA is.
"""

import numpy as np
import pytest
from pxr import Usd
from usd_stages import add_curves, chain, new_stage

import dftl_warp.core.model as model_module
from dftl_warp.output.qc import ATTRIBUTES
from dftl_warp.simulation.simulate import Simulation, simulate_usd


@pytest.fixture
def particle_major(monkeypatch):
    """Models built on the CPU take the particle-major layout (CUDA's), strands in Morton order."""
    monkeypatch.setattr(model_module, "default_layout", lambda device: "particle-major")


def _qc(path, prim, name, time=1.0):
    stage = Usd.Stage.Open(str(path))
    return stage.GetPrimAtPath(f"/dftl_qc/{prim}").GetAttribute(ATTRIBUTES[name]).Get(time)


def test_penetration_is_reported_under_the_prim_whose_strand_is_inside(tmp_path, particle_major):
    """Prim /World/Fur's two strands lie outside a sphere of radius 0.1 m; /World/Hair's second
    strand is rooted 5 cm inside it, so its particle 1 stays 4 cm deep (the root is kinematic and
    the segment 1 cm): (r + 0.04) / r = 41 hair radii of 1 mm, for /World/Hair alone."""
    from test_usd_features import sphere_collider

    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    fur = [chain(12, 0.01, direction=d, origin=(x, 0.15, 0.0)) for x in (-0.3, 0.35)]
    hair = [chain(12, 0.01, direction=(0.0, 1.0, 0.0), origin=o) for o in ((0.3, 0.3, 0.0), (0.0, 0.05, 0.0))]
    add_curves(stage, "/World/Fur", np.concatenate(fur), [12, 12], widths=0.002)
    add_curves(stage, "/World/Hair", np.concatenate(hair), [12, 12], widths=0.002)
    sphere_collider(stage, "/World/Ball", 0.1)
    stage.Save()
    out = tmp_path / "out.usdc"
    summary = simulate_usd(tmp_path / "in.usda", out, device="cpu", substeps=4)
    assert any("at /World/Hair strand 1, point 1:" in w for w in summary.start_notes), summary.start_notes
    assert _qc(out, "World_Hair", "penetration") == pytest.approx(41.0, rel=1e-3)
    assert _qc(out, "World_Fur", "penetration") == 0.0


def _two_heights(path):
    """Prims /World/Low (roots at y = 0, 0.4, 0.8) and /World/High (0.2, 0.6, 1.0), three hanging
    strands each: the Morton order of the roots mixes the prims' strands."""
    stage = new_stage(path, start=1, end=2)
    low = [chain(6, 0.01, direction=(0.0, -1.0, 0.0), origin=(0.0, y, 0.0)) for y in (0.0, 0.4, 0.8)]
    high = [chain(6, 0.01, direction=(0.0, -1.0, 0.0), origin=(0.0, y, 0.0)) for y in (0.2, 0.6, 1.0)]
    add_curves(stage, "/World/Low", np.concatenate(low), [6] * 3)
    add_curves(stage, "/World/High", np.concatenate(high), [6] * 3)
    stage.Save()
    return low, high


def test_energy_per_prim_is_the_potential_of_its_own_strands(tmp_path, particle_major):
    """At the first frame, before any step, the hair is at rest where it was authored: each prim's
    QC energy is sum over its free particles of -g . x per unit mass, 9.81 m/s^2 times the sum of
    their heights, whatever order the device keeps the strands in."""
    low, high = _two_heights(tmp_path / "in.usda")
    out = tmp_path / "out.usdc"
    simulate_usd(tmp_path / "in.usda", out, device="cpu", substeps=2)
    for prim, strands in (("World_Low", low), ("World_High", high)):
        heights = np.concatenate([s[1:, 1] for s in strands])   # free particles: roots excepted
        assert _qc(out, prim, "energy") == pytest.approx(9.81 * heights.sum(), rel=1e-5, abs=1e-6)


def test_the_layout_under_test_does_reorder_the_prims_strands(tmp_path, particle_major):
    """The tests above mean something only if the device order mixes the prims' strands."""
    import dftl_warp as dw
    from dftl_warp.simulation.settings import SimulationOptions

    _two_heights(tmp_path / "in.usda")
    sim = Simulation(dw.read_scene(str(tmp_path / "in.usda")), SimulationOptions(device="cpu"), 1)
    (group,) = sim.groups
    assert group.model.layout.name == "particle-major"
    order = group.model.layout.strand_order
    assert sorted(order[:3]) != [0, 1, 2], order   # the first three device strands are not all /World/Low's
