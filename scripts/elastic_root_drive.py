#!/usr/bin/env python3
"""Written velocities against the central difference of the written points on a shaken root
(docs/elastic.md, "Velocities against the central difference"): the elastic strand L = l_b of
scripts/elastic_study.py, started at its equilibrium (inverse statics), its root moved
y = A (1 - cos 2 pi t) / 2 (A = 1 cm, 1 Hz), 8 substeps per 24 fps frame, 48 frames; p1 / median /
p99 of |v| / |central difference| where the central difference is at least 10% of its largest.

Three drives of the same root: the Control's linear path (no root velocities: the root's
velocity is the frame's mean and jumps every frame), the Control's C1 path (root velocities at the
frame's ends from the frames' positions, ``dftl_warp.core.state.frame_velocity``, as
``simulate_usd`` sets them; docs/elastic.md, velocities) and the exact path set before every
substep. World space (the Control's), not the written local velocities of a USD output
(tests/test_root_path.py measures those).

    python scripts/elastic_root_drive.py [--damping S]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
import elastic_study as es  # noqa: E402

AMPLITUDE = 0.01  # m
SUBSTEPS = 8
FRAMES = 48


def ratios(drive: str, damping: float | None) -> np.ndarray:
    from dftl_warp.core.state import frame_velocity

    _, _, _, _, lb = es.material()
    options = {} if damping is None else {"damping": damping}
    model, solver, state, control = es.setup(es.straight([lb]), inverse_statics=True, **options)
    y = lambda t: AMPLITUDE * (1 - np.cos(2 * np.pi * t)) / 2  # noqa: E731
    root = lambda t: np.array([[0.0, y(t), 0.0]])  # noqa: E731
    h = 1.0 / (es.FPS * SUBSTEPS)
    T = 1.0 / es.FPS
    at_frame = lambda f: root(f * T)  # noqa: E731
    xs, vs = [], []
    for f in range(FRAMES):
        if drive == "exact":
            for k in range(SUBSTEPS):
                control.set_root_targets(root((f + k / SUBSTEPS) / es.FPS), root((f + (k + 1) / SUBSTEPS) / es.FPS))
                solver.advance(state, control, h, 1)
        elif drive == "c1":   # the shot is frames 0 .. FRAMES
            control.set_root_targets(at_frame(f), at_frame(f + 1), frame_duration=T,
                                     velocity_start=frame_velocity(at_frame, f, 0, FRAMES, T),
                                     velocity_end=frame_velocity(at_frame, f + 1, 0, FRAMES, T))
            solver.advance(state, control, h, SUBSTEPS)
        else:
            control.set_root_targets(at_frame(f), at_frame(f + 1))
            solver.advance(state, control, h, SUBSTEPS)
        xs.append(es.points(model, state, (es.N + 1, 3)))
        vs.append(model.points_from_device(state.velocities, relative=False).reshape(es.N + 1, 3))
    x, v = np.array(xs), np.array(vs)
    cd = np.linalg.norm((x[2:] - x[:-2]) * es.FPS / 2, axis=-1)
    speed = np.linalg.norm(v[1:-1], axis=-1)
    moving = cd >= 0.1 * cd.max()
    return np.percentile(speed[moving] / cd[moving], [1, 50, 99])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--damping", type=float, default=None, help="the elastic solver's s (default: its default)")
    args = ap.parse_args()
    wp.config.quiet = True
    wp.init()
    print(f"damping: {'the solver default' if args.damping is None else args.damping}")
    for name, drive in (("linear across the frame (the Control, no root velocities)", "linear"),
                        ("on the Control's C1 path (root velocities from the frames)", "c1"),
                        ("exact at every substep", "exact")):
        p1, med, p99 = ratios(drive, args.damping)
        print(f"root {name}: |v| / |central difference| p1 {p1:.2f}, median {med:.2f}, p99 {p99:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
