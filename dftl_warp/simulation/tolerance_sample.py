"""The sample of ``--tolerance`` (:mod:`.tolerance`): one solver on a few evenly spaced strands of
a group, a *trial* state advanced ``k`` substeps per frame in the group's precision and a
persistent *shadow* advanced ``2 k`` in float64, with the scene's roots, colliders and wind; their
difference is the error estimate. For an elastic group the sample is the elastic solver with the
group's material, inverse statics and rest shape (:func:`elastic_sample_options`) and clamps.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

#: convergence order of each solver's position error (measured; docs in :mod:`.tolerance`; the
#: elastic solver's by ``scripts/elastic_order.py``, docs/tolerance.md)
ORDER = {"dftl": 0.7, "ftl": 0.7, "pbd": 1.0, "elastic": 0.7, "rattle": 2.0, "reference": 2.0}
#: share of strands sampled, and the least number
SAMPLE_SHARE = 0.03
SAMPLE_MIN = 8


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


def rescale_corrections(model, state, old: int, new: int) -> None:
    """The prior form's carried correction of ``state``, last stepped at ``old`` substeps per frame,
    made the one of a step at ``new``: times ``(old / new)^2`` (a force times the step squared;
    ``kernels/simulation/tolerance.py`` says why and what it costs not to)."""
    if state.corrections is None or old == new or model.num_strands == 0:
        return
    import warp as wp

    from ..kernels.simulation.tolerance import scale_corrections_kernel

    wp.launch(scale_corrections_kernel(model.scalar), dim=model.num_strands, device=model.device,
              inputs=[model.strand_base, model.strand_stride, model.strand_count, (old / new) ** 2],
              outputs=[state.corrections])


def copy_state(src, src_model, dst, dst_model, points=None, strands=None) -> None:
    """``dst`` (a State of ``dst_model``) made ``src`` (of ``src_model``), through the host: points
    ``points`` and strands ``strands`` of ``src_model`` (input order; None: all) are ``dst_model``'s,
    in any precision. The elastic solver's States carry their tensions, material frames (per point)
    and clamp ghosts (per strand) along."""
    for name, relative in (("positions", True), ("velocities", False), ("corrections", False)):
        if getattr(dst, name, None) is None:
            continue
        values = getattr(src, name, None)
        if values is None:
            dst.write(name, None, zero=True)
            continue
        host = src_model.points_from_device(values, relative=relative)
        host = host if points is None else host[points]
        dst.write(name, dst_model.points_to_device(host, relative=relative))
    if getattr(dst, "frames", None) is None or getattr(src, "frames", None) is None:
        return
    src_lay, dst_lay = src_model.layout, dst_model.layout
    for name in ("tensions", "frames"):   # per point, device slots
        host = getattr(src, name).numpy()[src_lay.slot_of_point]
        out = getattr(dst, name).numpy()
        out[dst_lay.slot_of_point] = host if points is None else host[points]
        getattr(dst, name).assign(out)
    ghosts = np.zeros((src_model.num_strands, 3))   # per strand, device order, from the model's origin
    ghosts[src_lay.strand_order] = src.clamps.numpy() + np.asarray(src_model.origin, float)
    ghosts = ghosts if strands is None else ghosts[strands]
    dst.clamps.assign((ghosts[dst_lay.strand_order] - np.asarray(dst_model.origin, float)).astype(
        dst.clamps.numpy().dtype))


def elastic_sample_options(scene, group, frame: int, features, widths, points_idx, arithmetic=None):
    """(make_solver keywords, features) of the elastic solver on the points ``points_idx`` of an
    elastic ``group``: its material as the group's solver has it (:func:`~.elastic_setup.elastic_options`),
    the per-point keywords picked, the group's inverse statics and the rest shape its solver has now
    (the clean start may have made a pushed-out strand's shape its rest: ``rest_where_moved``), in
    ``arithmetic`` (None: the group's)."""
    from .elastic_setup import elastic_options
    from .split_elastic import PER_POINT

    extra, features = elastic_options(scene, group.curves, frame, features, widths, group.settings)
    for name in PER_POINT:
        value = extra.get(name)
        if value is not None and np.ndim(value) > 0:
            extra[name] = np.asarray(value)[points_idx]
    solver = group.solver
    extra["rest_shape"] = (solver._rest_points + np.asarray(group.model.origin, float))[points_idx]
    extra["inverse_statics"] = solver.inverse_statics
    extra["compute_precision"] = arithmetic or solver.compute_precision
    return extra, features


def same_rest(src, dst, frame: int) -> None:
    """``dst``, the elastic group ``src`` rebuilt (same prims, another precision), given the rest
    shapes of ``src``'s solver where they differ from its own by more than a hundredth of the hair
    radius (those the clean start made where it pushed strands out: ``rest_where_moved``), and its
    clamps made again from them. ``dst``'s state is left to be copied from ``src``'s."""
    from .elastic_setup import ClampDriver

    a, b = src.solver, dst.solver
    rest = a._rest_points + np.asarray(src.model.origin, float)   # world, input order
    away = np.abs(rest - (b._rest_points + np.asarray(dst.model.origin, float))).max(axis=1) > 1.0e-2 * b.radius
    strands = np.unique(np.repeat(np.arange(dst.num_strands), dst.model.counts)[away])
    if strands.size == 0:
        return
    dst.state.write("positions", dst.model.points_to_device(rest))
    b.adopt_rest_shape(dst.state, strands=strands)
    dst.clamps = ClampDriver(dst, frame)


class Lane:
    """The sample strands as one model in one precision: model, solver, control."""

    def __init__(self, group, scene, frame: int, solver: str, idx: np.ndarray, points_idx, precision: str,
                 arithmetic: str | None = None):
        import warp as wp

        from ..core.model import Model
        from ..features import group_features
        from ..solvers import build_solver, carries_corrections
        from ..usd.scene import transform_points

        settings = group.settings
        counts = np.concatenate([c.counts for c in group.curves])
        points = np.concatenate([transform_points(c.transform(frame), c.points) for c in group.curves])
        features, widths = group_features(scene, group.curves, frame)
        extra = {}
        if solver == "elastic":
            extra, features = elastic_sample_options(scene, group, frame, features, widths, points_idx, arithmetic)
        device = group.model.device
        with wp.ScopedDevice(device):
            self.model = Model.from_strands(
                points[points_idx], counts[idx], device=device, precision=precision, origin=group.model.origin,
                widths=None if widths is None else widths[points_idx],
                features=sample_features(features, idx, len(counts)),
                corrections=carries_corrections(solver, settings.correction))
            self.solver = build_solver(self.model, solver, damping=settings.damping, correction=settings.correction,
                                       gravity=scene.gravity, **extra)
            self.control = self.model.control()
        #: the frame the control was last set to reach (:meth:`SampleRun.set_frame`)
        self.reached = None

    def rewind_colliders(self) -> None:
        """Colliders back at the frame's start, for the previous substep too. The control's poses
        advance with each substep (the continuous test and friction use the motion since the
        previous one), so every run of a frame (``k``, ``2 k`` substeps) must start from the same
        poses: without this the second run's first substep swept the colliders back across the
        whole frame. Deforming meshes likewise (:meth:`~..features.colliders.mesh.MeshColliders.rewind`):
        the frame's last substep leaves them at its end, and a second run (the shadow on the trial's
        lane in float64, a retry at other substeps) saw them stand still there."""
        from ..features.colliders.device import inverse_poses

        c = None if self.control.features is None else self.control.features.colliders
        if c is None:
            return
        meshes = c.kind_data.get("meshes")
        if meshes is not None:
            meshes.rewind()
        start = c.pose_start.numpy()
        inverse = inverse_poses(start).astype(start.dtype)
        for a, v in ((c.pose, start), (c.pose_prev, start), (c.inv_pose, inverse), (c.inv_pose_prev, inverse)):
            a.assign(v)


class SampleRun:
    """One solver on the sample strands of a group: a *trial* state in the group's ``precision``,
    a persistent *shadow* (and ``work``, the shadow at the frame's end) in float64, so that the
    estimate also holds the trial's rounding error (float32's contact floor: :mod:`.tolerance`)."""

    def __init__(self, group, scene, frame: int, solver: str, idx: np.ndarray, precision: str):
        self.group, self.scene, self.idx, self.name = group, scene, idx, solver
        counts = np.concatenate([c.counts for c in group.curves])
        starts = np.concatenate([[0], np.cumsum(counts)])
        self.points_idx = np.concatenate([np.arange(starts[s], starts[s + 1]) for s in idx])
        self.lane = Lane(group, scene, frame, solver, idx, self.points_idx, precision)
        wide = precision == "float64"
        self.wide = self.lane if wide else Lane(group, scene, frame, solver, idx, self.points_idx, "float64",
                                                "float64")
        self.model, self.solver = self.lane.model, self.lane.solver
        self.trial = self.solver.state()
        self.shadow, self.work = self.wide.solver.state(), self.wide.solver.state()
        self.factor = richardson(solver)
        #: substeps per frame of the last step of the trial's and the shadow's states (their carried
        #: corrections are for that step: :func:`rescale_corrections`)
        self.trial_carried = self.shadow_carried = 1
        #: seconds per substep measured on the trial (wall clock, device synchronized)
        self.seconds_per_substep: list[float] = []

    def load(self, state, model) -> None:
        """The trial starts from the sample strands of a full-group ``state`` of ``model``."""
        copy_state(state, model, self.trial, self.model, self.points_idx, self.idx)

    def shadow_from_trial(self) -> None:
        """The shadow starts where the trial is."""
        copy_state(self.trial, self.model, self.shadow, self.wide.model)
        self.shadow_carried = self.trial_carried

    def set_frame(self, roots, frame: int, nxt: int, shot=None) -> None:
        """Root targets and features of the frame ``frame`` -> ``nxt``. ``roots``: the keyword
        arguments of :meth:`~dftl_warp.core.state.Control.set_root_targets` for the whole group
        (per-strand arrays in input order, picked here), and for the elastic solver under ``clamps``
        those of its ``set_clamp_targets`` (the clamps' rotations too), or None (still roots);
        ``shot``: the first and last frame, for roots bound to a mesh (None: not passed). A frame
        that does not follow the one last set (the plan went back) starts the colliders afresh
        (``resync``): its deforming meshes move from the frame's points. Roots
        bound to an animated mesh turn the elastic clamps with them, as the group's
        (:func:`~.root_paths.bound_clamps`)."""
        from ..features import update_frame

        clamps = None
        if roots is not None:
            roots = dict(roots)
            clamps = self._pick(roots.pop("clamps", None))
            roots = self._pick(roots)
        mesh = self.group.curves[0].root_mesh
        bound = self.name == "elastic" and mesh is not None and mesh.animated
        extra = {} if shot is None else {"shot": shot}
        for lane in {id(self.lane): self.lane, id(self.wide): self.wide}.values():
            if lane.reached != frame:
                # not the frame after the last set (the plan went back, or the first): deforming meshes
                # start at the frame's points, not where the last frame set left them (a later frame's)
                lane.control.features.resync()
            lane.reached = nxt
            if roots is not None:
                lane.control.set_root_targets(**roots)
            if clamps is not None:
                lane.solver.set_clamp_targets(**clamps)
            update_frame(self.scene, self.group.curves, lane.control, frame, nxt, **extra)
            if bound:
                lane.solver.bind_clamps(lane.control)

    def _pick(self, path):
        """The sample strands' rows of a group's per-strand arrays in ``path`` (a dict, or None)."""
        if path is None:
            return None
        n = self.group.num_strands
        return {key: (v[self.idx] if isinstance(v, np.ndarray) and v.ndim >= 2 and len(v) == n else v)
                for key, v in path.items()}

    def run(self, lane, source, out, frame_dt: float, k: int, carried: int) -> None:
        """``out``: ``source`` (last stepped at ``carried`` substeps per frame) advanced one frame
        by ``k`` substeps on ``lane``."""
        import warp as wp

        out.assign(source)
        rescale_corrections(lane.model, out, carried, k)
        lane.rewind_colliders()
        a = time.perf_counter()
        lane.solver.advance(out, lane.control, frame_dt / k, k)
        wp.synchronize_device(lane.model.device)
        if lane is self.lane:
            self.seconds_per_substep.append((time.perf_counter() - a) / k)

    def estimate(self, frame_dt: float, k: int, start) -> tuple[float, object]:
        """Estimated error at the frame's end of ``start`` advanced by ``k`` substeps (the trial
        state, which is left there) against the shadow advanced by ``2 k`` (left in ``work``)."""
        scratch = self.solver.state()
        scratch.assign(start)
        self.run(self.lane, scratch, self.trial, frame_dt, k, self.trial_carried)
        self.run(self.wide, self.shadow, self.work, frame_dt, 2 * k, self.shadow_carried)
        a = self.model.points_from_device(self.trial.positions)
        b = self.wide.model.points_from_device(self.work.positions)
        return self.factor * float(np.sqrt(((a - b) ** 2).sum(-1).mean())), scratch

    def results(self, kept=None) -> tuple:
        """Copies of the frame's results (the trial, and the shadow at the frame's end), or
        ``kept`` put back."""
        if kept is not None:
            self.trial.assign(kept[0])
            self.work.assign(kept[1])
            return kept
        trial, work = self.solver.state(), self.wide.solver.state()
        trial.assign(self.trial)
        work.assign(self.work)
        return trial, work

    def snapshot(self) -> tuple:
        """Copies of the trial and the shadow, with the substeps their corrections carry."""
        trial, shadow = self.solver.state(), self.wide.solver.state()
        trial.assign(self.trial)
        shadow.assign(self.shadow)
        return trial, shadow, self.trial_carried, self.shadow_carried

    def restore(self, snap: tuple) -> None:
        """Back to a :meth:`snapshot` (which stays valid)."""
        trial, shadow, self.trial_carried, self.shadow_carried = snap
        self.trial.assign(trial)
        self.shadow.assign(shadow)
