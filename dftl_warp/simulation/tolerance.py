"""``--tolerance LENGTH``: substeps (solver, precision) chosen per frame from an a-posteriori error estimate.

The estimator is step doubling on a deterministic sample of the group's strands
(:mod:`.tolerance_sample`: evenly spaced, about 3 %, at least 8), starting from the group's state
after its clean start:

- the *trial*: the sample advanced with the frame's ``k`` substeps, in the group's precision: what
  the simulation computes for those strands (strands step independently; with hair-hair the
  sample feels only itself);
- the *shadow*: a persistent copy of the sample in float64 that has run every frame with twice the
  trial's substeps since the start (float64, so that the estimate holds float32's rounding too,
  which step doubling in one precision cannot see).

Both take the group's root path (``simulation/root_paths.py``), colliders and wind; each run of a
frame starts from the frame's collider poses and deforming meshes' points
(:meth:`~.tolerance_sample.Lane.rewind_colliders`),
and DFTL's carried correction is rescaled whenever ``k`` changes (``kernels/simulation/tolerance.py``),
in the sample and in the group. Their difference estimates the *global* error of the run
(accumulated since the first frame, not one frame's local error), by Richardson:
``err(k) ~ |x_k - x_2k| / (1 - 2^-p)`` with ``p`` the solver's order
(:data:`~.tolerance_sample.ORDER`: 2 for rattle, 4/3 |x_k - x_2k|; 0.7 for DFTL, measured on the
falling chain against the reference, 2.6 |x_k - x_2k|; on the collider scene of
``tests/test_tolerance.py`` DFTL converges at order 1, so there the estimate is about 1.3 x the
error; 0.7 for the elastic solver too, measured against a fine run of itself:
``scripts/elastic_order.py``, docs/tolerance.md). The error of a frame is the RMS over the
sample's particles of that difference (stage units: the RMS position error over strand length, as
the accuracy study measures it); the run's error is its maximum over frames.

The choice (:class:`ToleranceController`), from the ladder 1, 2, 4, ... 1024, is planned on the
sample up to :data:`WINDOW` frames ahead of the simulation, because an error made now can grow
later (hair dragged by a head that turns back: choosing frame by frame, the collider scene ends
at 2.0 x the tolerance 0.005 and 18 x 0.0005; docs/tolerance.md). Per planned frame: while the estimate at the
end of the frame would exceed ``GROW`` x tolerance (or grow by more than ``RATE`` x tolerance in the
frame), double ``k``, while doubling lowers the estimate by a fifth at least (else the error is
inherited, and ``k`` stays); when it is below ``SHRINK`` x tolerance for ``HOLD`` frames and ``k / 2``
would stay below ``GROW / 2`` x tolerance, halve it. When a planned frame's estimate still exceeds
``LIMIT`` x tolerance, the plan goes back to the frame the simulation is at, doubles the substeps
of every frame from there to the offending one (a first-order error then halves) and plans again,
until the estimate stops falling by ``FALL`` or the substeps reach the top of the ladder. The
simulation takes each frame's ``k`` from the plan.

An elastic group's sample is the elastic solver with the group's per-point material, inverse
statics and rest shape, its clamps driven as the group's (:func:`frame_targets`), its States
carrying tensions, frames and clamp ghosts (:func:`~.tolerance_sample.copy_state`).

The solver (``solver`` unset, and the group not elastic: a prim with widths keeps the elastic
solver, its bending): each candidate (rattle, then dftl; rattle only without features)
runs the controller on the sample alone over the first :data:`PILOT_FRAMES` frames (a pilot, from
the scene's own roots and colliders), its cost per substep measured; the cheapest total cost wins
(:func:`pick_solver`). The precision: where the plan in float32 goes past the tolerance and the plan in
float64 stays within it, the group runs in float64 (a line says so; the run's precision option is then not
what ran: the record's ``group0.precision`` is). Why: with colliders float32 has an error floor that
grows with the substeps (contact and friction resolve displacements of order ``g dt^2``, near
float32's resolution): on the collider scene DFTL errs by 0.0028 at 64 substeps, 0.0077 at 256 and
0.031 at 1024 in float32, against 0.0023, 0.0006 and 0.00014 in float64 (docs/tolerance.md).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .tolerance_sample import SampleRun, copy_state, rescale_corrections, same_rest, sample_strands
from ..errors import plural

#: substeps per frame the controller may choose
LADDER = tuple(2 ** i for i in range(11))
#: grow when the end-of-frame estimate would exceed GROW x tolerance, or grow by more than RATE x
#: tolerance over the frame (the error made cannot be undone: it is spent slowly)
GROW = 0.8
RATE = 0.15
#: shrink when below SHRINK x tolerance for HOLD frames in a row (and k/2 stays below GROW/2)
SHRINK = 0.15
HOLD = 3
#: frames planned ahead of the simulation (0.5 s at 24 fps)
WINDOW = 12
#: a planned estimate above LIMIT x tolerance sends the plan back to raise earlier substeps; it goes
#: back again only while that lowered the offending frame's estimate by FALL
LIMIT = 1.0
FALL = 0.8
#: frames the solver pilot runs
PILOT_FRAMES = 12
#: the candidates of the automatic solver choice, in order of preference at equal cost
CANDIDATES = ("rattle", "dftl")
#: the output record with the estimates (writer.set_record)
RECORD = "dftl:tolerance"


class ToleranceController:
    """Chooses a group's substeps per frame so that the estimated error stays below ``tolerance``.

    ``roots(f)``: the group's root targets over the frame ``f`` -> ``f + 1`` (keyword arguments of
    ``Control.set_root_targets``, or None: still); ``last``: the last frame (nothing is planned past
    it); ``shot``: passed on to ``update_frame`` (None: not); ``carried``: the substeps of the group
    state's last step."""

    def __init__(self, run: SampleRun, tolerance: float, roots, last: int, k: int = 1, carried: int = 1,
                 shot=None):
        self.sample, self.tolerance = run, float(tolerance)
        self.roots, self.last, self.shot = roots, int(last), shot
        self.k = int(k)
        #: substeps per frame of the group state's last step (its carried corrections are for it)
        self.carried = int(carried)
        #: per frame (the frame reached): (frame, substeps, estimated error), as simulated
        self.history: list[tuple[int, int, float]] = []
        #: lines saying what changed
        self.changes: list[str] = []
        #: planned frame -> (substeps, estimated error); frame -> least substeps (raised by going back)
        self.plan: dict[int, tuple[int, float]] = {}
        self.floor: dict[int, int] = {}
        #: frame -> the sample and the controller at its start (to go back to)
        self._marks: dict[int, tuple] = {}
        #: offending frame -> its estimate when the plan last went back for it
        self._offended: dict[int, float] = {}
        #: no going back for frames before this one (going back stopped helping)
        self._futile_until = -1
        self._cursor = None
        self._below = 0
        self._prev = 0.0
        self._frame_dt = None
        self._chosen = None

    # -- planning on the sample ------------------------------------------------------------------

    def start(self, frame: int, frame_dt: float, state=None, model=None) -> None:
        """Start at ``frame`` from the group's ``state`` of ``model`` (None: the sample's own start)."""
        s = self.sample
        if state is not None:
            s.load(state, model)
            s.trial_carried = self.carried
        s.shadow_from_trial()
        self._frame_dt = float(frame_dt)
        self._cursor = int(frame)
        self._mark(self._cursor)

    def _mark(self, g: int) -> None:
        self._marks[g] = (self.sample.snapshot(), self.k, self._below, self._prev)

    def _back_to(self, g: int) -> None:
        snap, self.k, self._below, self._prev = self._marks[g]
        self.sample.restore(snap)
        for h in [h for h in self.plan if h >= g]:
            del self.plan[h]
        for h in [h for h in self._marks if h > g]:
            del self._marks[h]
        self._cursor = g

    def _plan_frame(self, g: int) -> None:
        """Choose the substeps of frame ``g`` -> ``g + 1`` (the sample at its start) and step to its end."""
        s, tol, prev, dt = self.sample, self.tolerance, self._prev, self._frame_dt
        s.set_frame(self.roots(g), g, g + 1, self.shot)
        least = self.floor.get(g, LADDER[0])
        k = first = max(self.k, least)
        err, start = s.estimate(dt, k, s.trial)

        def too_much(e):
            return e > GROW * tol or e - prev > RATE * tol

        while too_much(err) and k < LADDER[-1]:
            kept = s.results()
            err2, _ = s.estimate(dt, 2 * k, start)
            if err2 >= 0.8 * err:   # inherited: a finer step in this frame does not help; keep k
                s.results(kept)
                break
            k, err = 2 * k, err2
        if k == first and err < SHRINK * tol and err - prev < 0.25 * RATE * tol and k // 2 >= least:
            self._below += 1
            if self._below >= HOLD:
                self._below = 0
                kept = s.results()
                err_half, _ = s.estimate(dt, k // 2, start)
                if err_half < 0.5 * GROW * tol and err_half - prev < 0.5 * RATE * tol:
                    k, err = k // 2, err_half
                else:   # keep k: put its trial and shadow back
                    s.results(kept)
        else:
            self._below = 0
        s.shadow.assign(s.work)
        s.trial_carried, s.shadow_carried = k, 2 * k
        self.k, self._prev = k, err
        self.plan[g] = (k, err)
        self._cursor = g + 1
        self._mark(g + 1)

    def look_ahead(self, frame: int) -> None:
        """Plan up to :data:`WINDOW` frames past ``frame`` (the frame the simulation is at), going
        back to ``frame`` to raise the substeps where a planned estimate passes the tolerance."""
        upto = max(frame, min(frame + WINDOW, self.last) - 1)
        while self._cursor <= upto:
            g = self._cursor
            self._plan_frame(g)
            err = self.plan[g][1]
            if err <= LIMIT * self.tolerance:
                continue
            if g < self._futile_until:
                continue
            before = self._offended.get(g)
            if before is not None and err > FALL * before:
                # going back did not help enough (the error is the solver's floor, or inherited from
                # frames already simulated): not again for a window
                self._futile_until = g + WINDOW
                continue
            window = range(frame, g + 1)
            if min(self.plan[h][0] for h in window) >= LADDER[-1]:
                continue
            self._offended[g] = err
            for h in window:   # a first-order error halves where every step does
                self.floor[h] = min(LADDER[-1], max(self.floor.get(h, 1), 2 * self.plan[h][0]))
            self._back_to(frame)

    def planned_max(self) -> float:
        """The largest estimate simulated or planned so far."""
        return max([e for _, _, e in self.history] + [e for _, e in self.plan.values()], default=0.0)

    # -- the simulation's frames -------------------------------------------------------------------

    def choose(self, frame_dt: float, roots, frame: int, nxt: int, state=None, model=None) -> int:
        """Substeps for the frame ``frame`` -> ``nxt`` (from the plan); ``state`` / ``model``: the
        group's state at the first frame (None: the sample's own start, as in the pilot).
        ``roots`` is unused (the controller's ``roots(f)`` gives every frame's)."""
        if self._cursor is None:
            self.start(frame, frame_dt, state, model)
        self.look_ahead(frame)
        k, err = self.plan.pop(frame)
        self._marks.pop(frame, None)
        self.floor.pop(frame, None)
        if k != self._chosen:
            self.changes.append(f"frame {frame}: {self.sample.name} {k} substeps (estimated error {err:.3g})")
        self._chosen = self.carried = k
        self.history.append((nxt, k, err))
        return k

    @property
    def max_error(self) -> float:
        return max((e for _, _, e in self.history), default=0.0)

    def cost(self) -> float:
        """Seconds per strand the sample would have spent on the frames so far at its choices."""
        per_step = float(np.median(self.sample.seconds_per_substep)) if self.sample.seconds_per_substep else 0.0
        return per_step * sum(k for _, k, _ in self.history)


def pick_solver(group, scene, frame: int, last: int, tolerance: float, precision: str, roots,
                shot=None) -> tuple[str, list[str]]:
    """The candidate solver with the lowest measured cost over a pilot of the first frames, and the
    lines saying so. ``roots``, ``shot``: as :class:`ToleranceController` takes them."""
    idx = sample_strands(group.num_strands)
    frame_dt = 1.0 / scene.stage.time_codes_per_second
    last = min(last, frame + PILOT_FRAMES)
    runs = []
    for name in CANDIDATES:
        try:
            runs.append((name, SampleRun(group, scene, frame, name, idx, precision)))
        except ValueError:   # rattle refuses features
            continue
    if len(runs) < 2:
        return (runs[0][0] if runs else group.settings.solver), []
    results = []
    for name, run in runs:
        ctl = ToleranceController(run, tolerance, roots, last, shot=shot)
        for f in range(frame, last):
            ctl.choose(frame_dt, None, f, f + 1)
        results.append((ctl.cost(), name, ctl))
    results.sort(key=lambda r: r[0])
    lines = [f"tolerance {tolerance:g}: pilot of {plural(len(idx), 'strand')}: " + ", ".join(
        f"{name} up to {max((k for _, k, _ in c.history), default=1)} substeps, {cost * 1e3:.3g} ms"
        for cost, name, c in results) + f"; chose {results[0][1]}"]
    return results[0][1], lines


class Tolerance:
    """A simulation's ``--tolerance``: one controller per group (:func:`setup` builds it)."""

    def __init__(self, tolerance: float, warn=None, source: str = ""):
        self.tolerance = float(tolerance)
        self.controllers: list[ToleranceController] = []
        #: what the pilot chose, one line per group
        self.notes: list[str] = []
        #: called once per group with a one-line warning when a frame's estimate passes the tolerance
        self.warn = warn
        self.source = source
        #: per group: its prims' paths, as the lines name the group
        self.names: list[str] = []
        self._unmet: set = set()

    def substeps(self, index: int, group, frame_dt: float, roots, frame: int, nxt: int) -> int:
        """Substeps of group ``index`` for the frame ``frame`` -> ``nxt`` (its control already set);
        the group's carried corrections are rescaled to them."""
        c = self.controllers[index]
        carried = c.carried
        k = c.choose(frame_dt, roots, frame, nxt, group.state, group.model)
        rescale_corrections(group.model, group.state, carried, k)
        err = c.history[-1][2]
        if err > self.tolerance and index not in self._unmet and self.warn is not None:
            self._unmet.add(index)
            most = " (the most it takes)" if k >= LADDER[-1] else ""
            self.warn(f"{self.source}: {self.names[index]}: --tolerance {self.tolerance:g} not met from frame {frame}: "
                      f"estimated error {err:.3g} ({err / self.tolerance:.1f}x) at {k} substeps per frame{most}; "
                      "the record dftl:tolerance has every frame's estimate")
        return k

    def lines(self) -> list[str]:
        """What was chosen: the pilot's lines, each change, and one summary line per group."""
        out = list(self.notes)
        for i, c in enumerate(self.controllers):
            out += [f"{self.names[i]}: {line}" for line in c.changes]
            ks = [k for _, k, _ in c.history]
            if ks:
                out.append(f"{self.names[i]}: tolerance {self.tolerance:g}: {c.sample.name}, {min(ks)}..{max(ks)} "
                           f"substeps per frame (mean {np.mean(ks):.3g}), largest estimated error "
                           f"{c.max_error:.3g} on {plural(len(c.sample.idx), 'sampled strand')}")
        return out

    def record(self) -> dict:
        """The output record (:data:`RECORD`): the tolerance, and per group the solver and, per frame
        reached, the substeps and the estimated error (space-separated, in frame order)."""
        rec = {"tolerance": self.tolerance,
               "estimator": "step doubling on sampled strands: RMS position error over strand length, "
                            "Richardson from k and 2k substeps (stage units)"}
        for i, c in enumerate(self.controllers):
            rec[f"group{i}.prims"] = self.names[i]
            rec[f"group{i}.solver"] = c.sample.name
            rec[f"group{i}.precision"] = str(c.sample.model.precision)
            rec[f"group{i}.strands_sampled"] = int(len(c.sample.idx))
            rec[f"group{i}.frames"] = " ".join(str(int(f)) for f, _, _ in c.history)
            rec[f"group{i}.substeps"] = " ".join(str(int(k)) for _, k, _ in c.history)
            rec[f"group{i}.error"] = " ".join(f"{e:.6g}" for _, _, e in c.history)
            rec[f"group{i}.max_error"] = float(c.max_error)
        return rec


def frame_targets(sim, k: int):
    """``roots(f)``: group ``k``'s root targets over the frame ``f`` -> ``f + 1``, as the simulation
    sets them (keyword arguments of ``Control.set_root_targets``; None where no prim of the group is
    animated), with the elastic solver's clamp targets under ``clamps`` (``set_clamp_targets``'s,
    the clamps' rotations too: they turn with the prims' transforms)."""
    from . import root_paths

    members = sim.groups[k].members
    animated = any(sim.scene.curves[i].animated for i in members)

    def roots(f):
        if not animated:
            return None
        g = sim.groups[k]   # the group as it is now (setup may rebuild it)
        path = root_paths.frame_path(sim, "roots", k, g, f, f + 1)
        if g.clamps is not None:
            path["clamps"] = root_paths.frame_path(sim, "clamps", k, g, f, f + 1)
        return path

    return roots


def setup(sim, tolerance: float) -> Tolerance:
    """Pick each group's solver (where none is set) by a pilot and its precision by the plan, and
    attach a controller per group."""
    from ..errors import UserError
    from . import root_paths
    from .group import Group
    from .settings import resolve_frames

    t = Tolerance(tolerance, sim.warn, sim.scene.source)   # kept in the run's warnings, shown as it happens
    scene, options, frame = sim.scene, sim.options, sim.frame
    last = resolve_frames(scene, options.start, options.end)[1]
    frame_dt = 1.0 / scene.stage.time_codes_per_second
    for k, g in enumerate(sim.groups):
        if len(g.devices) > 1:
            raise UserError("--tolerance runs on one device for now (give one --device)")
        roots = frame_targets(sim, k)
        name = ", ".join(scene.curves[i].path for i in g.members)   # the lines name the group by its prims
        t.names.append(name)

        def rebuilt(g, settings, precision):
            new = Group(settings, g.members, scene, frame, replace(options, precision=precision), g.input_strands)
            if settings.solver == "elastic":   # the rest shapes the clean start gave pushed-out strands
                same_rest(g, new, frame)
            copy_state(g.state, g.model, new.state, new.model)   # the clean start's push-out and preroll kept
            return new

        # the elastic solver is the hair's bending, not a cheaper way to the same motion: it is kept
        auto = (options.solver is None and g.settings.solver != "elastic"
                and all(scene.curves[i].settings.solver is None for i in g.members))
        if auto:
            name, lines = pick_solver(g, scene, frame, last, tolerance, options.precision, roots,
                                      root_paths.shot(sim))
            t.notes += [f"{name}: {line}" for line in lines]
            if name != g.settings.solver:
                g = sim.groups[k] = rebuilt(g, replace(g.settings, solver=name), options.precision)

        def controller(g, precision):
            run = SampleRun(g, scene, frame, g.settings.solver, sample_strands(g.num_strands), precision)
            c = ToleranceController(run, tolerance, roots, last, carried=g.settings.substeps,
                                    shot=root_paths.shot(sim))
            c.start(frame, frame_dt, g.state, g.model)
            c.look_ahead(frame)
            return c

        c = controller(g, options.precision)
        if options.precision == "float32" and c.planned_max() > LIMIT * tolerance:
            wide = controller(g, "float64")
            if wide.planned_max() <= LIMIT * tolerance:
                t.notes.append(f"{name}: tolerance {tolerance:g}: runs in float64: planned in float32 the "
                               f"estimate reaches {c.planned_max():.3g}, in float64 {wide.planned_max():.3g}")
                g = sim.groups[k] = rebuilt(g, g.settings, "float64")
                c = wide
        t.controllers.append(c)
    return t
