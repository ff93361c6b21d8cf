"""The elastic solver with features (CPU): colliders of every registered shape after its
follow-the-leader projection (as the featured DFTL sweep), their per-frame poses, a styled groom on
a head collider with inverse statics, drag and wind in the implicit solve, and the features it
refuses."""

from __future__ import annotations

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.features.colliders import Ellipsoid
from dftl_warp.solvers.elastic import HAIR_DENSITY, HAIR_E

R = 40e-6          # 80 um hair
N = 32
FPS = 24.0
EI = HAIR_E * np.pi * R ** 4 / 4
LB = (EI / (HAIR_DENSITY * np.pi * R ** 2 * 9.81)) ** (1.0 / 3.0)   # bending length, 4.93 cm
SUB = 8


def box_mesh(half):
    """Closed box mesh (8 points, 12 outward-facing triangles) of half extents ``half``."""
    hx, hy, hz = half
    p = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return p, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def mesh_box():
    p, i = box_mesh((0.08, 0.05, 0.08))
    return F.TriangleMesh(points=p, indices=i, friction=0.3)


def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


# signed distances (m) of collider-local points q (P, 3) to each test shape
def sd_sphere(q, r=0.1):
    return np.linalg.norm(q, axis=1) - r


def sd_capsule(q, r=0.06, half=0.1):            # axis Z
    axial = np.clip(q[:, 2], -half, half)
    return np.linalg.norm(q - axial[:, None] * [0, 0, 1], axis=1) - r


def sd_box(q, half=(0.08, 0.05, 0.08)):
    d = np.abs(q) - half
    return np.linalg.norm(np.maximum(d, 0), axis=1) + np.minimum(d.max(axis=1), 0)


def sd_ellipsoid(q, radii=(0.12, 0.08, 0.1)):
    """Exact distance of points outside the ellipsoid (bisection on the closest point's
    Lagrange multiplier), negative inside (the scaled-radius estimate there)."""
    a = np.asarray(radii, float)
    y = np.abs(q)
    k = np.linalg.norm(q / a, axis=1)
    lo, hi = np.zeros(len(q)), np.linalg.norm(y, axis=1) * a.max() + 1e-12
    for _ in range(200):
        t = 0.5 * (lo + hi)
        g = np.sum((a * y / (t[:, None] + a * a)) ** 2, axis=1) - 1
        lo, hi = np.where(g > 0, t, lo), np.where(g > 0, hi, t)
    x = a * a * y / (lo[:, None] + a * a)
    return np.where(k >= 1, np.linalg.norm(y - x, axis=1), (k - 1) * a.min())


SHAPES = {
    "sphere": (lambda: F.Sphere(radius=0.1, friction=0.3), sd_sphere, 0.1),
    "capsule": (lambda: F.Capsule(radius=0.06, half_height=0.1, axis="Z", friction=0.3), sd_capsule, 0.06),
    "box": (lambda: F.Box(half_extents=(0.08, 0.05, 0.08), friction=0.3), sd_box, 0.05),
    "ellipsoid": (lambda: Ellipsoid(radii=(0.12, 0.08, 0.1), friction=0.3), sd_ellipsoid, 0.08),
    "mesh": (lambda: mesh_box(), sd_box, 0.05),
}


def segment_lengths(x):
    return np.linalg.norm(np.diff(x, axis=1), axis=-1)


#: (shape, turning): every shape still and turning. Before the convex-edge fixes (a contact plane
#: out of the leader's reach answered by the face the segment enters, kernels/features/mesh.py and
#: the box's entry face in kernels/features/analytic.py), a *turning* box left particles 38-43 hair
#: radii inside its edges (29-30 with 4 rounds), with the featured DFTL sweep as with this solver.
CASES = [(s, t) for s in ("sphere", "capsule", "ellipsoid", "box", "mesh") for t in (False, True)]


@pytest.mark.parametrize("shape,turning", CASES, ids=[f"{s}-{'turning' if t else 'still'}" for s, t in CASES])
def test_hair_draped_on_a_collider_stays_outside_and_keeps_its_lengths(shape, turning):
    """Horizontal strands (L = 4 l_b) fall onto the shape and drape over it for 1.5 s; the shape
    turns +-30 degrees about the vertical through its poses (``set_collider_poses``) when
    ``turning``. Every substep: no particle nearer the surface than the hair radius minus 1e-3 of
    it, segment lengths exact."""
    make, sd, top = SHAPES[shape]
    L = 4 * LB
    xs = np.linspace(-0.03, 0.03, 5)
    pts = np.stack([np.stack([np.full(N + 1, x), np.full(N + 1, top + 0.002), np.linspace(0, L, N + 1) - 0.03], 1)
                    for x in xs])
    model = dw.Model.from_strands(pts.reshape(-1, 3), [N + 1] * len(xs), widths=2 * R, precision="float64",
                                  features=[F.Colliders([make()])])
    solver = dw.make_solver(model, "elastic", inverse_statics=False)
    state, control = solver.state(), model.control()
    rest = segment_lengths(pts)
    angle = (lambda t: np.radians(30) * np.sin(2 * np.pi * t / 1.5)) if turning else (lambda t: 0.0)

    def pose(t):
        a = angle(t)
        return [[0, 0, 0, 0, np.sin(a / 2), 0, np.cos(a / 2)]]

    worst, stretch, touching = -np.inf, 0.0, 0
    for f in range(36):
        control.features.set_collider_poses(pose(f / FPS), pose((f + 1) / FPS))
        for k in range(SUB):
            solver.step(state, state, control, 1.0 / (FPS * SUB), (k + 1) / SUB)
            x = model.points_from_device(state.positions)
            a0, a1 = angle(f / FPS), angle((f + 1) / FPS)
            q = x @ rot_y(a0 + (k + 1) / SUB * (a1 - a0))   # collider-local R^T x (poses slerped in a frame)
            free = np.ones(len(x), bool)
            free[:: N + 1] = False                    # roots are kinematic
            d = sd(q[free])
            worst = max(worst, (R - d).max() / R)
            touching = max(touching, int(np.sum(d < 1.5 * R)))
            stretch = max(stretch, np.abs(segment_lengths(x.reshape(pts.shape)) / rest - 1).max())
    assert touching > 20                              # the hair does lie on the shape
    assert worst <= 1e-3, worst
    assert stretch < 1e-12, stretch


def head_groom(sr=0.1):
    """Styled strands rooted on a sphere head of radius ``sr``: each leaves the scalp along the
    normal and arcs downward (some curled), staying at least 2 mm off the head."""
    rng = np.random.default_rng(3)
    strands = []
    while len(strands) < 12:
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        if n[1] < 0.3:
            continue
        down = np.array([0.0, -1.0, 0.0]) - n * -n[1]
        down /= np.linalg.norm(down)
        side = np.cross(n, down)
        L = rng.uniform(0.08, 0.16)
        s = np.linspace(0, L, N + 1)
        turn = rng.uniform(1.5, 2.4) * s / L                  # from the normal toward the down direction
        curl = 0.004 * np.sin(2 * np.pi * rng.uniform(1, 3) * s / L) if len(strands) % 3 == 0 else 0 * s
        t = np.cos(turn)[:, None] * n + np.sin(turn)[:, None] * down
        t = t + np.gradient(curl)[:, None] / (L / N) * side
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        x = sr * n + np.concatenate([[np.zeros(3)], np.cumsum(0.5 * (t[1:] + t[:-1]) * (L / N), axis=0)])
        if (np.linalg.norm(x[1:], axis=1) - sr).min() > 0.002:
            strands.append(x)
    return np.array(strands)


@pytest.mark.parametrize("precision,bound", [("float64", 1e-10), ("float32", 1e-6)])
def test_styled_groom_on_a_sphere_head_stays_as_authored(precision, bound):
    """Inverse statics on a head collider: the authored shape is the equilibrium, the head supports
    nothing, nothing moves (2 s at 8 substeps)."""
    sr = 0.1
    pts = head_groom(sr)
    model = dw.Model.from_strands(pts.reshape(-1, 3), [N + 1] * len(pts), widths=2 * R, precision=precision,
                                  features=[F.Colliders([F.Sphere(radius=sr, friction=0.3)])])
    solver = dw.make_solver(model, "elastic")
    state, control = solver.state(), model.control()
    for _ in range(48):
        solver.advance(state, control, 1.0 / (FPS * SUB), SUB)
    x = model.points_from_device(state.positions).reshape(pts.shape)
    L = segment_lengths(pts).sum(axis=1)
    moved = (np.linalg.norm(x - pts, axis=-1).max(axis=1) / L).max()
    assert moved < bound, moved


def test_drag_feature_is_the_solvers_drag():
    """The Drag feature acts in the implicit solve exactly as the solver's ``drag`` option."""
    rest = np.stack([np.linspace(0, 2 * LB, N + 1), np.zeros(N + 1), np.zeros(N + 1)], 1)
    runs = []
    for features, drag in (([F.Drag(5.0)], 0.0), ([], 5.0)):
        model = dw.Model.from_strands(rest, [N + 1], precision="float64", features=features)
        solver = dw.make_solver(model, "elastic", radius=R, drag=drag, inverse_statics=False)
        state, control = solver.state(), model.control()
        for _ in range(12):
            solver.advance(state, control, 1.0 / (FPS * SUB), SUB)
        runs.append(model.points_from_device(state.positions))
    assert np.array_equal(runs[0], runs[1])
    assert np.abs(runs[0] - rest).max() > 0.1 * LB      # it did move


@pytest.mark.parametrize("noise", [0.0, 0.5])
def test_wind_blows_a_hanging_strand_downstream(noise):
    """A hanging strand L = 4 l_b in a 2 m/s wind along +x (drag 2/s, with or without curl noise)
    leans downstream by about the drag-to-weight angle; lengths stay exact."""
    L = 4 * LB
    rest = np.stack([np.zeros(N + 1), -np.linspace(0, L, N + 1), np.zeros(N + 1)], 1)
    wind = F.Wind(velocity=(2.0, 0.0, 0.0), noise_amplitude=noise, noise_scale=0.05)
    model = dw.Model.from_strands(rest, [N + 1], precision="float64", features=[F.Drag(2.0), wind])
    solver = dw.make_solver(model, "elastic", radius=R)
    state, control = solver.state(), model.control()
    for f in range(48):
        control.features.set_frame_time(f / FPS, (f + 1) / FPS)
        solver.advance(state, control, 1.0 / (FPS * SUB), SUB)
    x = model.points_from_device(state.positions)
    lean = np.degrees(np.arctan2(x[-1, 0], -x[-1, 1]))
    assert 8 < lean < 23         # a string would lean atan(drag * wind / g) = 22 deg; the clamped root holds it back
    assert np.abs(segment_lengths(x[None]) / segment_lengths(rest[None]) - 1).max() < 1e-12


def test_unknown_features_are_refused_by_name():
    """Every feature type there is runs elastic (root binding too: tests/test_elastic_binding.py); a
    feature the solver does not know (one added later without its elastic part) is refused by name."""
    rest = np.stack([np.linspace(0, LB, N + 1), np.zeros(N + 1), np.zeros(N + 1)], 1)
    binding = F.RootBinding(np.array([[0.0, 0, -1], [1, 0, 1], [-1, 0, 1]]), np.array([[0, 1, 2]]))
    model = dw.Model.from_strands(rest, [N + 1], features=[F.Colliders([F.Sphere(radius=0.01)]), binding])
    dw.make_solver(model, "elastic")

    class Magnetism:
        flags = frozenset()

    object.__setattr__(model, "features", model.features + (Magnetism(),))
    with pytest.raises(ValueError, match="supports colliders, drag, wind, hair-hair and root binding only.*Magnetism"):
        dw.make_solver(model, "elastic")
