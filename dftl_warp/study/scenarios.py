"""Standard scenarios of the accuracy study and their analytic answers (numpy only).

- :func:`horizontal_chain`: the DFTL literature's test, a chain along +x released under gravity;
- :func:`hanging_chain_modes` / :func:`hanging_chain_in_mode`: the linearized small oscillations
  of a hanging chain of equal masses and a chain started in one mode shape;
- :func:`pendulum_period`: the large-amplitude period of a pendulum (complete elliptic integral
  by the arithmetic-geometric mean);
- :func:`groom` / :func:`head_roots`: a small groom hanging from a spherical head that turns and nods;
- :func:`hair_cantilever` / :func:`hair_helix` / :func:`shaken_roots`: elastic strands (80 um hair,
  :data:`HAIR_RADIUS`) and a root shaken to and fro;
- :func:`folded_strands`: strands folded tighter than a right angle at every joint, moving fast
  (what a collider leaves when it drags hair through itself; docs/accuracy/folded.md);
- :func:`record`: run any solver over frames and record the trajectory.

Units: metres, seconds, m/s^2. Gravity is along -Y.
"""

from __future__ import annotations

import numpy as np

from ..core.layout import strand_offsets
GRAVITY = 9.81


def horizontal_chain(particles: int, length: float = 1.0, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(particles, 3) points of a straight chain of total ``length`` along +x, root first."""
    spacing = length / max(particles - 1, 1)
    return np.asarray(origin, dtype=np.float64) + np.arange(particles)[:, None] * np.array([spacing, 0.0, 0.0])


def elliptic_k(k: float) -> float:
    """Complete elliptic integral of the first kind K(k) (modulus k), by the AGM."""
    a, b = 1.0, float(np.sqrt(1.0 - k * k))
    for _ in range(60):
        a, b = 0.5 * (a + b), float(np.sqrt(a * b))
        if abs(a - b) < 1e-16 * a:
            break
    return float(np.pi / (2.0 * a))


def pendulum_period(length: float, gravity: float, amplitude: float) -> float:
    """Period (s) of a pendulum of ``length`` (m) swinging to ``amplitude`` (rad):
    ``T = 4 sqrt(l/g) K(sin(amplitude/2))``."""
    return 4.0 * np.sqrt(length / gravity) * elliptic_k(np.sin(0.5 * amplitude))


def pendulum(length: float, amplitude: float) -> np.ndarray:
    """(2, 3) points: pivot at the origin, bob at ``amplitude`` (rad) from straight down."""
    return np.array([[0.0, 0.0, 0.0], [length * np.sin(amplitude), -length * np.cos(amplitude), 0.0]])


def hanging_chain_modes(masses: int, segment: float, gravity: float = GRAVITY):
    """Small horizontal oscillations of ``masses`` equal masses hanging below a fixed root.

    Segment ``j`` (1 = at the root) carries the weight of the ``masses - j + 1`` masses below it,
    so ``y'' = -(g/l) A y`` with ``A`` tridiagonal. Returns (angular frequencies (rad/s),
    ascending; mode shapes as columns, unit norm, positive at the tip).
    """
    n = masses
    tension = (n - np.arange(1, n + 2) + 1).astype(np.float64)  # tension[j-1] = T_j / (m g), T_{n+1} = 0
    tension[-1] = 0.0
    a = np.zeros((n, n))
    for i in range(n):  # particle i+1
        a[i, i] = tension[i] + tension[i + 1]
        if i > 0:
            a[i, i - 1] = -tension[i]
        if i < n - 1:
            a[i, i + 1] = -tension[i + 1]
    eig, vec = np.linalg.eigh(a)
    vec = vec * np.sign(vec[-1])
    return np.sqrt(eig * gravity / segment), vec


def hanging_chain_in_mode(masses: int, segment: float, shape, amplitude: float) -> np.ndarray:
    """(masses + 1, 3) points of a chain hanging from the origin, displaced along x by
    ``amplitude * shape`` (m) with every segment exactly ``segment`` long."""
    y = np.concatenate([[0.0], amplitude * np.asarray(shape, dtype=np.float64)])
    pts = np.zeros((masses + 1, 3))
    for i in range(1, masses + 1):
        dx = y[i] - y[i - 1]
        pts[i] = pts[i - 1] + np.array([dx, -np.sqrt(segment * segment - dx * dx), 0.0])
    return pts


def groom(strands: int = 64, particles: int = 16, length: float = 0.2, head_radius: float = 0.1, seed: int = 7,
          hanging: bool = True):
    """A small groom: ``strands`` straight strands of ``particles`` points and ``length`` (m)
    rooted on the upper half of a sphere of ``head_radius`` centred at the origin, hanging
    straight down at rest (``hanging``, the default) or growing along the surface normal.
    Returns (points (N, 3), counts (S,)). There are no collisions: strands may cross the head."""
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(strands, 3))
    normals[:, 1] = np.abs(normals[:, 1]) + 0.2
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    steps = np.linspace(0.0, length, particles)
    direction = np.broadcast_to([0.0, -1.0, 0.0], normals.shape) if hanging else normals
    points = head_radius * normals[:, None, :] + steps[None, :, None] * direction[:, None, :]
    return points.reshape(-1, 3), np.full(strands, particles, dtype=np.int64)


def head_roots(roots0: np.ndarray, t: float) -> np.ndarray:
    """Root positions (S, 3) at time ``t`` (s) of a head that turns (yaw 0.6 rad at 1.5 Hz)
    and nods (pitch 0.3 rad at 1 Hz) about its centre while bobbing 3 cm at 2 Hz."""
    yaw = 0.6 * np.sin(2.0 * np.pi * 1.5 * t)
    pitch = 0.3 * np.sin(2.0 * np.pi * 1.0 * t)
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    r_yaw = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    r_pitch = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    bob = np.array([0.0, 0.03 * np.sin(2.0 * np.pi * 2.0 * t), 0.0])
    return roots0 @ (r_yaw @ r_pitch).T + bob


#: elastic strands: the hair radius of the study's scenarios (80 um hair), m
HAIR_RADIUS = 40e-6


def hair_cantilever(length: float, segments: int = 32) -> np.ndarray:
    """(segments + 1, 3) points of a straight strand of ``length`` (m) along +x from the origin."""
    return horizontal_chain(segments + 1, length)


def hair_helix(length: float = 0.2, turns: float = 2.0, radius: float = 0.015, segments: int = 32) -> np.ndarray:
    """(segments + 1, 3) points of a helix of ``turns`` turns of ``radius`` (m) hanging down (-y)
    from the origin, ``segments`` equal segments of total ``length`` (m): a styled curl."""
    s = np.linspace(0.0, length, segments + 1)
    c = length / np.sqrt((2 * np.pi * turns * radius) ** 2 + length ** 2)
    angle = 2 * np.pi * turns * s / length
    pts = np.stack([radius * (np.cos(angle) - 1), -s * c, radius * np.sin(angle)], axis=-1)
    seg = np.diff(pts, axis=0)
    seg *= (length / segments) / np.linalg.norm(seg, axis=1, keepdims=True)
    return np.concatenate([pts[:1], pts[:1] + np.cumsum(seg, axis=0)])


def shaken_roots(roots0: np.ndarray, amplitude: float = 0.02, frequency: float = 2.0):
    """Root targets ``t -> roots0 + amplitude sin(2 pi frequency t) x`` (m, Hz): a head shaken sideways."""
    roots0 = np.asarray(roots0, dtype=np.float64)
    return lambda t: roots0 + np.array([amplitude * np.sin(2.0 * np.pi * frequency * t), 0.0, 0.0])


def folded_strands(count: int, points: int = 16, segment: float = 0.005, speed: float = 0.7, seed: int = 1):
    """(count * points, 3) positions and velocities (m, m/s) of ``count`` strands of ``points``
    particles ``segment`` apart from roots 0.1 m apart along x (too far apart to meet): the first
    segment hangs along -y, then every joint turns by an angle drawn in [100, 175] degrees about a
    random axis. Each free particle's velocity is drawn on its own, its components normal with
    deviation ``speed``: along the segments too, as a collider's push leaves hair, which the links
    then correct; the roots are still."""
    rng = np.random.default_rng(seed)
    positions, velocities = [], []
    for s in range(count):
        directions = [np.array([0.0, -1.0, 0.0])]
        for turn in np.radians(rng.uniform(100.0, 175.0, points - 2)):
            axis = rng.normal(size=3)
            axis -= axis.dot(directions[-1]) * directions[-1]
            axis /= np.linalg.norm(axis)
            d = directions[-1] * np.cos(turn) + np.cross(axis, directions[-1]) * np.sin(turn)
            directions.append(d / np.linalg.norm(d))
        root = np.array([0.1 * s, 0.0, 0.0])
        positions.append(np.vstack([root, root + segment * np.cumsum(directions, 0)]))
        v = rng.normal(size=(points, 3)) * speed
        v[0] = 0.0
        velocities.append(v)
    return np.concatenate(positions), np.concatenate(velocities)


def strand_starts(counts) -> np.ndarray:
    return strand_offsets(counts)


def record(solver, frames: int, frame_dt: float, substeps: int, *, roots=None, velocities=None,
           state=None, control=None, monitor=None, clock=None):
    """Run ``solver`` for ``frames`` frames of ``frame_dt`` s, ``substeps`` steps each.

    ``roots(t)`` (optional) gives the world root targets (S, 3) at time ``t``; within a frame the
    roots move linearly. Returns (positions, velocities), each (frames + 1, N, 3) float64 in
    input order and world space; frame 0 is the initial state. ``monitor.check`` is called
    after every frame when a monitor is given. ``clock`` (a list) receives the wall-clock seconds
    of every frame's ``solver.advance`` (device synchronized; recording and monitoring excluded).
    """
    import time

    import warp as wp

    model = solver.model
    state = solver.state() if state is None else state
    control = model.control() if control is None else control
    if velocities is not None:
        state.write("velocities", model.points_to_device(velocities, relative=False))
    dt = frame_dt / substeps
    spent = []
    pos = [model.points_from_device(state.positions)]
    vel = [model.points_from_device(state.velocities, relative=False)]
    for f in range(frames):
        if roots is not None:
            control.set_root_targets(roots(f * frame_dt), roots((f + 1) * frame_dt))
        start = time.perf_counter()
        solver.advance(state, control, dt, substeps)
        wp.synchronize_device(model.device)
        spent.append(time.perf_counter() - start)
        if monitor is not None:
            monitor.check(state, f + 1)
        pos.append(model.points_from_device(state.positions))
        vel.append(model.points_from_device(state.velocities, relative=False))
    if clock is not None:
        clock.extend(spent)
    return np.stack(pos), np.stack(vel)
