"""A deforming mesh collider's two meshes swap roles every substep (ping-pong).

Every substep of a frame in which a mesh collider's points move, the step queries the mesh at this
substep's points and at the previous substep's. Before, the collider's own mesh got this
substep's points and a second mesh the previous substep's, both written and both BVHs refitted
every substep (two refits per substep, and one more when the points were set). The previous
substep's points are those the other mesh got a substep ago, so now the meshes swap roles: one
write and one refit per substep, two in a frame's first (whose previous points are the frame's
start, which neither mesh holds), none when the points are set. The step sees the same points in
each mesh at every query, so the hair moves bit for bit as before (``MeshColliders._ping_pong =
False`` is the old path); the energy monitor and ``mesh_now`` read the mesh the step sees now.
"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from test_deforming_motion import FPS, HALF, RADIUS, Y, box_distance, box_mesh, hanging_hair

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.features.colliders.mesh import MeshColliders
from dftl_warp.simulation.monitor_colliders import ColliderMotion

FRAMES = 9
SPEED = 1.0          # m/s: 42 mm a frame, 30 times the box's depth band
STOP = 4 / FPS       # s: the box stops after 4 frames (17 cm), 5 frames before the end


def box_at(t, z=0.0, stop=STOP):
    """The 8 cm box's points at time t: from x = -7 cm at SPEED, turning about z and growing
    (a deformation, not a rigid motion), until ``stop``."""
    box, _ = box_mesh(HALF)
    t = min(t, stop)
    a = 3.0 * t
    turn = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    return box @ turn.T * (1.0 + 0.5 * t) + [-0.07 + SPEED * t, Y, z]


def scene(two=False):
    pts, counts = hanging_hair()
    _, tris = box_mesh(HALF)
    shapes = [F.TriangleMesh(points=box_at(0.0), indices=tris)]
    if two:   # a second box beside the first (5 cm along z), moving alike
        shapes.append(F.TriangleMesh(points=box_at(0.0, 0.05), indices=tris))
    model = dw.Model.from_strands(pts, counts, widths=2 * RADIUS, device="cpu", features=[F.Colliders(shapes)])
    solver = dw.DFTLSolver(model, gravity=(0.0, -9.81, 0.0))
    return model, solver, len(shapes)


def clearance(x, t):
    """The hair's smallest distance (m) to the box at time t, particles inside negative (roots
    excluded)."""
    free = np.delete(x, np.arange(9) * 16, axis=0)
    t = min(t, STOP)
    a = -3.0 * t
    undo = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    local = (free - [-0.07 + SPEED * t, Y, 0.0]) @ undo.T
    return box_distance(local, np.zeros(3), HALF * (1.0 + 0.5 * t)).min()


def run(substeps, ping_pong, monkeypatch, two=False, restore_at=None, skip=None):
    """Positions after each frame of the box moving through the hair (then still), and the hair's
    smallest distance to the box at the end (m). ``restore_at``: that frame is run, then the state
    restored to before it (a checkpoint: resync, its points set with their ``start``) and the frame
    run again; ``skip``: the frame whose points are not set (the mesh keeps still; its motion
    resumes a frame late)."""
    monkeypatch.setattr(MeshColliders, "_ping_pong", ping_pong)
    model, solver, n = scene(two)
    state, control = solver.state(), model.control()
    names = [a for a in ("positions", "velocities", "corrections") if getattr(state, a) is not None]
    frames = []
    for f in range(FRAMES):
        late = 1 if skip is not None and f > skip else 0
        t0, t1 = (f - late) / FPS, (f + 1 - late) / FPS
        for again in ([False, True] if f == restore_at else [False]):
            if f == restore_at and not again:
                saved = {a: getattr(state, a).numpy().copy() for a in names}
            if again:
                for a in names:
                    getattr(state, a).assign(saved[a])
                control.features.resync()
            if f != skip:
                for i in range(n):
                    z = 0.05 * i
                    control.features.set_mesh_points(i, box_at(t1, z), start=box_at(t0, z) if again else None)
            solver.advance(state, control, 1.0 / FPS / substeps, substeps)
        frames.append(model.points_from_device(state.positions))
    return np.array(frames), clearance(frames[-1], FRAMES / FPS)


@pytest.mark.parametrize("substeps", [8, 7])
@pytest.mark.parametrize("case", [dict(), dict(restore_at=3), dict(skip=1), dict(two=True)])
def test_the_hair_moves_bit_for_bit_as_with_two_refits_and_stays_outside_the_box(substeps, case, monkeypatch):
    """8 and 7 substeps (the frame ends on either mesh), a checkpoint restored mid-run, a frame
    whose points are not set, two boxes: the ping-pong and the old two refits per substep give the
    same positions bit for bit after every frame; the box pushed the hair, and once it has stopped
    no particle is more than its hair radius inside it."""
    x, clear = run(substeps, True, monkeypatch, **case)
    old, _ = run(substeps, False, monkeypatch, **case)
    assert np.array_equal(x, old)
    assert clear > -(RADIUS + 1e-4), clear
    pts, _ = hanging_hair()
    assert np.abs(x[-1] - pts).max() > 0.05         # the box pushed the hair (5 cm and more)


def test_a_restored_checkpoint_continues_as_the_uninterrupted_run(monkeypatch):
    """Restoring the state before a frame (resync, its points set with their start) and running it
    again gives what running it once gave: the meshes' roles start afresh with the frame."""
    for substeps in (8, 7):
        once, _ = run(substeps, True, monkeypatch)
        again, _ = run(substeps, True, monkeypatch, restore_at=3)
        assert np.array_equal(once, again)


def count_refits(monkeypatch):
    """Refits per mesh id, counted as they happen (wp.Mesh.refit wrapped)."""
    counts = {}
    refit = wp.Mesh.refit

    def counted(self):
        counts[self.id] = counts.get(self.id, 0) + 1
        return refit(self)

    monkeypatch.setattr(wp.Mesh, "refit", counted)
    return counts


@pytest.mark.parametrize("substeps", [8, 7, 1])
def test_one_refit_per_moving_mesh_and_substep_two_in_a_frames_first(substeps, monkeypatch):
    """Per moving mesh: no refit when its points are set, two in a frame's first substep, one in
    every other (before: one when set and two every substep); each substep refits the mesh the step
    then queries as the current one, and a frame's refits follow the same sequence of meshes
    whatever ran before it (a CUDA graph captured once replays them)."""
    monkeypatch.setattr(MeshColliders, "_ping_pong", True)
    model, solver, n = scene(two=True)
    state, control = solver.state(), model.control()
    meshes = control.features.colliders.kind_data["meshes"]
    counts = count_refits(monkeypatch)
    advance = meshes.advance
    per_substep, sequences = [], []

    def counted_advance(alpha):
        counts.clear()
        advance(alpha)
        per_substep.append(dict(counts))
        for i in range(n):   # the mesh refitted last is the one the step queries as current
            assert meshes.mesh_now(i).id in counts

    monkeypatch.setattr(meshes, "advance", counted_advance)
    for f, k in enumerate([substeps, substeps, 7, substeps, 8, substeps]):
        counts.clear()
        for i in range(n):
            control.features.set_mesh_points(i, box_at((f + 1) / FPS, 0.05 * i, stop=np.inf))
        assert counts == {}                   # setting moving points refits nothing
        per_substep.clear()
        solver.advance(state, control, 1.0 / FPS / k, k)
        assert len(per_substep) == k
        assert [sum(c.values()) for c in per_substep] == [2 * n] + [n] * (k - 1)
        assert all(set(c.values()) == {1} for c in per_substep)
        if k == substeps:
            sequences.append([sorted(c) for c in per_substep])
    assert all(s == sequences[0] for s in sequences)


def test_the_old_path_refits_twice_per_substep(monkeypatch):
    """The private switch keeps the old path (the reference above): one refit when the points are
    set, two per substep."""
    monkeypatch.setattr(MeshColliders, "_ping_pong", False)
    model, solver, _ = scene()
    state, control = solver.state(), model.control()
    counts = count_refits(monkeypatch)
    control.features.set_mesh_points(0, box_at(1 / FPS))
    solver.advance(state, control, 1.0 / FPS / 8, 8)
    assert sum(counts.values()) == 1 + 2 * 8


def test_the_energy_monitor_reads_the_mesh_where_the_frame_left_it(monkeypatch):
    """After a frame of 7 substeps the last substep's points are in the second mesh: the energy
    monitor's reach (ColliderMotion: a sphere about the collider's origin that holds it over the
    frame) holds the box grown to twice its size at the frame's end, not at its sixth substep's
    (1 6/7 times), and ``mesh_now`` is that mesh."""
    monkeypatch.setattr(MeshColliders, "_ping_pong", True)
    model, solver, _ = scene()
    state, control = solver.state(), model.control()
    monitor = ColliderMotion(control, 1.0 / FPS)
    end = 2.0 * box_at(0.0)
    control.features.set_mesh_points(0, end)
    solver.advance(state, control, 1.0 / FPS / 7, 7)
    monitor.update(True)
    assert float(monitor.reach.numpy()[0]) == pytest.approx(float(np.linalg.norm(end, axis=1).max()), rel=1e-6)
    meshes = control.features.colliders.kind_data["meshes"]
    assert np.allclose(meshes.mesh_now(0).points.numpy(), end, atol=1e-6)
