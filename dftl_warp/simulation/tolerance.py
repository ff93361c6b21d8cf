"""``--tolerance LENGTH``: substeps (and solver) chosen per frame from an a-posteriori error estimate.

The estimator is step doubling on a deterministic sample of the group's strands (:func:`sample_strands`:
evenly spaced, about 3 %, at least 8), run beside the simulation:

- the *trial*: each frame, a copy of the sample's current state (taken from the simulation) is
  advanced with the frame's ``k`` substeps; it is what the simulation itself computes for those
  strands;
- the *shadow*: a persistent copy of the sample that has run every frame with twice the
  simulation's substeps since the start.

Both share the scene's roots, colliders and wind. Their difference estimates the *global* error of
the run (accumulated since the first frame, not one frame's local error), by Richardson:
``err(k) ~ |x_k - x_2k| / (1 - 2^-p)`` with ``p`` the solver's order (:data:`ORDER`: 2 for
rattle, 4/3 |x_k - x_2k|; about 0.7 for DFTL, measured on the falling chain against the
reference, 2.6 |x_k - x_2k|). The error of a frame is the RMS over the sample's particles of that
difference (stage units: the RMS position error over strand length, as the accuracy study measures
it); the run's error is its maximum over frames.

The choice per frame (:meth:`ToleranceController.choose`), from the ladder 1, 2, 4, ... 1024:
while the estimate at the end of the frame would exceed ``GROW`` x tolerance, double ``k`` (stop
when doubling no longer helps: the error is inherited from earlier frames); when it is below
``SHRINK`` x tolerance for ``HOLD`` frames and ``k / 2`` would stay below ``GROW / 2`` x tolerance,
halve it. The error already made cannot be undone, so growing is early (``GROW`` < 1).

The solver (``solver`` unset): each candidate (rattle, then dftl; rattle only without features)
runs the controller on the sample alone over the first frames (a pilot, from the scene's own roots
and colliders), its cost per substep measured; the cheapest total cost wins
(:func:`pick_solver`).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

#: substeps per frame the controller may choose
LADDER = tuple(2 ** i for i in range(11))
#: convergence order of each solver's position error (measured; docs in the module string)
ORDER = {"dftl": 0.7, "ftl": 0.7, "pbd": 1.0, "elastic": 1.0, "rattle": 2.0, "reference": 2.0}
#: grow when the end-of-frame estimate would exceed GROW x tolerance, or grow by more than RATE x
#: tolerance over the frame (the error made cannot be undone: it is spent slowly)
GROW = 0.8
RATE = 0.15
#: shrink when below SHRINK x tolerance for HOLD frames in a row (and k/2 stays below GROW/2)
SHRINK = 0.15
HOLD = 3
#: share of strands sampled, and the least number
SAMPLE_SHARE = 0.03
SAMPLE_MIN = 8
#: frames the solver pilot runs
PILOT_FRAMES = 12
#: the candidates of the automatic solver choice, in order of preference at equal cost
CANDIDATES = ("rattle", "dftl")
#: the output record with the estimates (writer.set_record)
RECORD = "dftl:tolerance"


def richardson(solver: str) -> float:
    """Factor from |x_k - x_2k| to the error of the k run: 1 / (1 - 2^-p)."""
    return 1.0 / (1.0 - 2.0 ** -ORDER.get(solver, 1.0))


def sample_strands(num_strands: int, share: float = SAMPLE_SHARE, least: int = SAMPLE_MIN) -> np.ndarray:
    """Evenly spaced strand indices: ``share`` of them, at least ``least`` (all when fewer)."""
    n = min(num_strands, max(least, int(math.ceil(share * num_strands))))
    return np.unique(np.linspace(0, num_strands - 1, n).round().astype(np.int64))


def sample_features(features, idx: np.ndarray, num_strands: int) -> list:
    """The features of strands ``idx``: per-strand values picked, scene-wide ones shared."""
    from ..features import Drag, RootBinding

    def pick(values):
        v = np.asarray(values)
        return values if v.ndim == 0 or v.shape[0] != num_strands else v[idx]

    out = []
    for f in features:
        if isinstance(f, RootBinding) and f.triangles is not None:
            f = replace(f, triangles=pick(f.triangles), weights=pick(f.weights))
        elif isinstance(f, Drag):
            f = replace(f, rate=pick(f.rate))
        out.append(f)
    return out


class SampleRun:
    """One solver on the sample strands of a group: a trial state, a persistent shadow, a control."""

    def __init__(self, group, scene, frame: int, solver: str, idx: np.ndarray, precision: str):
        import warp as wp

        from ..core.model import Model
        from ..features import group_features
        from ..solvers import carries_corrections, make_solver
        from ..usd.scene import transform_points

        self.group, self.scene, self.idx, self.name = group, scene, idx, solver
        settings = group.settings
        counts = np.concatenate([c.counts for c in group.curves])
        starts = np.concatenate([[0], np.cumsum(counts)])
        self.points_idx = np.concatenate([np.arange(starts[s], starts[s + 1]) for s in idx])
        points = np.concatenate([transform_points(c.transform(frame), c.points) for c in group.curves])
        features, widths = group_features(scene, group.curves, frame)
        device = group.model.device
        with wp.ScopedDevice(device):
            self.model = Model.from_strands(
                points[self.points_idx], counts[idx], device=device, precision=precision, origin=group.model.origin,
                widths=None if widths is None else widths[self.points_idx],
                features=sample_features(features, idx, len(counts)),
                corrections=carries_corrections(solver, settings.correction))
            self.solver = make_solver(self.model, solver, damping=settings.damping, correction=settings.correction,
                                      gravity=scene.gravity)
            self.trial, self.shadow, self.work = (self.solver.state() for _ in range(3))
            self.control = self.model.control()
        self.factor = richardson(solver)
        #: seconds per substep measured on the sample (wall clock, device synchronized)
        self.seconds_per_substep: list[float] = []

    def load(self, state, model) -> None:
        """The trial starts from the sample strands of a full-group ``state`` of ``model``."""
        m = self.model
        for name, relative in (("positions", True), ("velocities", False), ("corrections", False)):
            if getattr(self.trial, name) is None:
                continue
            src = getattr(state, name, None)
            if src is None:
                self.trial.write(name, None, zero=True)
                continue
            pts = model.points_from_device(src, relative=relative)[self.points_idx]
            self.trial.write(name, m.points_to_device(pts, relative=relative), layout=m.layout)

    def set_frame(self, roots, frame: int, nxt: int) -> None:
        """Root targets (world, the group's strands in input order, or None: still) and features."""
        from ..features import update_frame

        if roots is not None:
            self.control.set_root_targets(roots[0][self.idx], roots[1][self.idx])
        update_frame(self.scene, self.group.curves, self.control, frame, nxt)

    def run(self, source, out, frame_dt: float, k: int) -> None:
        import warp as wp

        out.assign(source)
        a = time.perf_counter()
        self.solver.advance(out, self.control, frame_dt / k, k)
        wp.synchronize_device(self.model.device)
        self.seconds_per_substep.append((time.perf_counter() - a) / k)

    def estimate(self, frame_dt: float, k: int, start) -> tuple[float, object]:
        """Estimated error at the frame's end of ``start`` advanced by ``k`` substeps (the trial
        state, which is left there) against the shadow advanced by ``2 k`` (left in ``work``)."""
        scratch = self.solver.state()
        scratch.assign(start)
        self.run(scratch, self.trial, frame_dt, k)
        self.run(self.shadow, self.work, frame_dt, 2 * k)
        a = self.model.points_from_device(self.trial.positions)
        b = self.model.points_from_device(self.work.positions)
        return self.factor * float(np.sqrt(((a - b) ** 2).sum(-1).mean())), scratch


class ToleranceController:
    """Chooses a group's substeps per frame so that the estimated error stays below ``tolerance``."""

    def __init__(self, run: SampleRun, tolerance: float, k: int = 1):
        self.sample, self.tolerance = run, float(tolerance)
        self.k = int(k)
        self.below = 0
        #: per frame (the frame reached): (frame, substeps, estimated error)
        self.history: list[tuple[int, int, float]] = []
        #: lines saying what changed
        self.changes: list[str] = []
        self._started = False

    def choose(self, frame_dt: float, roots, frame: int, nxt: int, state=None, model=None) -> int:
        """Substeps for the frame ``frame`` -> ``nxt``; ``state`` / ``model``: the group's current
        state (None: the sample's own trial continues, as in the pilot)."""
        s = self.sample
        if not self._started:
            s.load(state, model) if state is not None else None
            s.shadow.assign(s.trial)
            self._started = True
        elif state is not None:
            s.load(state, model)
        s.set_frame(roots, frame, nxt)
        start = s.trial
        k, tol = self.k, self.tolerance
        err, start = s.estimate(frame_dt, k, start)
        old = k
        prev = self.history[-1][2] if self.history else 0.0

        def too_much(e):
            return e > GROW * tol or e - prev > RATE * tol

        while too_much(err) and k < LADDER[-1]:
            err2, _ = s.estimate(frame_dt, 2 * k, start)
            helped = err2 < 0.8 * err
            k, err = 2 * k, err2
            if not helped:
                break
        if k == old and err < SHRINK * tol and err - prev < 0.25 * RATE * tol and k > LADDER[0]:
            self.below += 1
            if self.below >= HOLD:
                trial = s.solver.state()
                trial.assign(s.trial)
                shadow = s.solver.state()
                shadow.assign(s.work)
                err_half, _ = s.estimate(frame_dt, k // 2, start)
                if err_half < 0.5 * GROW * tol and err_half - prev < 0.5 * RATE * tol:
                    k, err = k // 2, err_half
                    self.below = 0
                else:   # keep k: put its trial and shadow back
                    s.trial.assign(trial)
                    s.work.assign(shadow)
                    self.below = 0
        else:
            self.below = 0
        s.shadow.assign(s.work)
        if k != self.k or not self.history:
            self.changes.append(f"frame {frame}: {s.name} {k} substeps (estimated error {err:.3g})")
        self.k = k
        self.history.append((nxt, k, err))
        return k

    @property
    def max_error(self) -> float:
        return max((e for _, _, e in self.history), default=0.0)

    def cost(self) -> float:
        """Seconds per strand the sample would have spent on the frames so far at its choices."""
        per_step = float(np.median(self.sample.seconds_per_substep)) if self.sample.seconds_per_substep else 0.0
        return per_step * sum(k for _, k, _ in self.history)


def pick_solver(group, scene, frame: int, last: int, tolerance: float, precision: str, roots) -> tuple[str, list[str]]:
    """The candidate solver with the lowest measured cost over a pilot of the first frames, and the
    lines saying so. ``roots(f)``: the group's world roots at frame ``f`` (None when still)."""
    idx = sample_strands(group.num_strands)
    frame_dt = 1.0 / scene.stage.time_codes_per_second
    results = []
    for name in CANDIDATES:
        try:
            run = SampleRun(group, scene, frame, name, idx, precision)
        except ValueError:   # rattle refuses features
            continue
        ctl = ToleranceController(run, tolerance)
        for f in range(frame, min(last, frame + PILOT_FRAMES)):
            r0, r1 = roots(f), roots(f + 1)
            ctl.choose(frame_dt, None if r0 is None else (r0, r1), f, f + 1)
        results.append((ctl.cost(), name, ctl))
    if not results:
        return group.settings.solver, []
    results.sort(key=lambda r: r[0])
    lines = [f"tolerance {tolerance:g}: pilot of {len(idx)} strands: " + ", ".join(
        f"{name} up to {max((k for _, k, _ in c.history), default=1)} substeps, {cost * 1e3:.3g} ms"
        for cost, name, c in results) + f"; chose {results[0][1]}"]
    return results[0][1], lines


class Tolerance:
    """A simulation's ``--tolerance``: one controller per group (:func:`setup` builds it)."""

    def __init__(self, tolerance: float):
        self.tolerance = float(tolerance)
        self.controllers: list[ToleranceController] = []
        #: what the pilot chose, one line per group
        self.notes: list[str] = []

    def substeps(self, index: int, group, frame_dt: float, roots, frame: int, nxt: int) -> int:
        """Substeps of group ``index`` for the frame ``frame`` -> ``nxt`` (its control already set)."""
        return self.controllers[index].choose(frame_dt, roots, frame, nxt, group.state, group.model)

    def lines(self) -> list[str]:
        """What was chosen: the pilot's lines, each change, and one summary line per group."""
        out = list(self.notes)
        for i, c in enumerate(self.controllers):
            out += [f"group {i}: {line}" for line in c.changes]
            ks = [k for _, k, _ in c.history]
            if ks:
                out.append(f"group {i}: tolerance {self.tolerance:g}: {c.sample.name}, {min(ks)}..{max(ks)} "
                           f"substeps per frame (mean {np.mean(ks):.3g}), largest estimated error "
                           f"{c.max_error:.3g} on {len(c.sample.idx)} sampled strands")
        return out

    def record(self) -> dict:
        """The output record (:data:`RECORD`): the tolerance, and per group the solver and, per frame
        reached, the substeps and the estimated error (space-separated, in frame order)."""
        rec = {"tolerance": self.tolerance,
               "estimator": "step doubling on sampled strands: RMS position error over strand length, "
                            "Richardson from k and 2k substeps (stage units)"}
        for i, c in enumerate(self.controllers):
            rec[f"group{i}.solver"] = c.sample.name
            rec[f"group{i}.strands_sampled"] = int(len(c.sample.idx))
            rec[f"group{i}.frames"] = " ".join(str(int(f)) for f, _, _ in c.history)
            rec[f"group{i}.substeps"] = " ".join(str(int(k)) for _, k, _ in c.history)
            rec[f"group{i}.error"] = " ".join(f"{e:.6g}" for _, _, e in c.history)
            rec[f"group{i}.max_error"] = float(c.max_error)
        return rec


def setup(sim, tolerance: float) -> Tolerance:
    """Pick each group's solver (where none is set) by a pilot and attach a controller per group."""
    from ..errors import UserError
    from .group import Group

    t = Tolerance(tolerance)
    scene, options, frame = sim.scene, sim.options, sim.frame
    for k, g in enumerate(sim.groups):
        if len(g.devices) > 1:
            raise UserError("--tolerance runs on one device for now (give one --device)")
        if g.settings.solver == "elastic":
            raise UserError("--tolerance does not drive the elastic solver yet")
        animated = any(scene.curves[i].animated for i in g.members)

        def roots(f, g=g, animated=animated):
            return sim._roots_world(g, f) if animated else None

        auto = options.solver is None and all(scene.curves[i].settings.solver is None for i in g.members)
        if auto:
            name, lines = pick_solver(g, scene, frame, frame + PILOT_FRAMES, tolerance, options.precision, roots)
            t.notes += lines
            if name != g.settings.solver:
                g = sim.groups[k] = Group(replace(g.settings, solver=name), g.members, scene, frame, options)
        run = SampleRun(g, scene, frame, g.settings.solver, sample_strands(g.num_strands), options.precision)
        t.controllers.append(ToleranceController(run, tolerance))
    return t
