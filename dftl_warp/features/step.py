"""The features of a model, composed: validation and kernel flags, the Model's device data
(:class:`ModelFeatures`), the Control's per-frame data (:class:`FeatureControl`, as
``control.features``) and one featured step (:class:`FeatureStep`, in the solver), which
launches the collider poses, the hair-hair grid, then the sweep specialized to the present
features (``kernels/solvers/featured.py``).

Each feature's own parameters, device data, per-frame control and USD mapping live in its module
(:mod:`~dftl_warp.features.colliders`, :mod:`~dftl_warp.features.binding`,
:mod:`~dftl_warp.features.air`, :mod:`~dftl_warp.features.hair_hair`). Device coordinates are relative to ``model.origin`` (m).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.precision import numpy_type
from ..core.state import AbsentFeatures
from ..kernels.features.air_grid import blocks_per_strand, split_flags, velocity_features_kernel
from ..kernels.features.collide import collider_flags, collider_pose_kernel
from ..kernels.features.mesh import mesh_substep_kernel
from ..kernels.features.step import feature_struct
from . import air, binding, colliders, hair_hair
from .air import Drag, Wind
from .base import find
from .binding import RootBinding
from .colliders import Colliders
from .hair_hair import HairHair

FEATURE_TYPES = (Colliders, RootBinding, Drag, Wind, HairHair)

#: hair-hair, drag and wind run in their own pass before the sweep
#: (``kernels/features/air_grid.py``), the sweep keeping the colliders only; False keeps them in
#: the sweep (the same arithmetic: ``scripts/profile_features.py --no-velocity-pass`` compares)
VELOCITY_PASS = True

#: CUDA threads per block of the featured sweep: at its 150-160 registers a multiprocessor holds one
#: block of 256 (8 warps) but three of 128 (12 warps); H200, 1M production scene: 9.71 -> 9.15 ms
#: (docs/benchmarks.md; ``scripts/profile_features.py --block-dims`` measures others)
SWEEP_BLOCK_DIM = 128

#: where ``root_alpha`` and ``dt`` sit in the DFTL sweep's leading inputs (``DFTLSolver.feature_head``)
HEAD_ROOT_ALPHA, HEAD_DT = 7, 10


def velocity_pass_flags(flags) -> tuple:
    """``(pass_flags, sweep_flags)`` of a feature flag set: what the velocity pass applies (empty
    when :data:`VELOCITY_PASS` is off) and what the sweep kernel is built for."""
    flags = frozenset(flags)
    if not VELOCITY_PASS or not flags:
        return frozenset(), flags
    return split_flags(flags)


def check_features(features) -> tuple:
    """Validate a feature list: known types, at most one of each, wind only with drag."""
    features = tuple(features or ())
    seen = set()
    for f in features:
        if not isinstance(f, FEATURE_TYPES):
            raise ValueError(f"unknown feature {f!r}; use one of {', '.join(t.__name__ for t in FEATURE_TYPES)}")
        if type(f) in seen:
            raise ValueError(f"feature {type(f).__name__} given twice")
        seen.add(type(f))
    if Wind in seen and Drag not in seen:
        raise ValueError("Wind acts through air drag: add a Drag feature")
    return features


def feature_flags(features) -> frozenset:
    """Kernel flags of ``features`` (the empty set for a gravity-only scene)."""
    flags = frozenset()
    for f in check_features(features):
        flags |= f.flags
    return flags


class ModelFeatures:
    """The immutable device data of a model's features (see :func:`build`).

    ``colliders``: the Colliders feature (shapes in the user's order) or None, its device data
    ``collider_data`` and ``collider_order`` (device index of each user collider); ``arrays``:
    per-strand arrays (drag rate); ``binding``: the root binding's
    triangles and weights; ``grid_shape``/``grid_cell``: the hair-hair grid's nodes and cell (m)."""

    def __init__(self, features, flags, arrays, collider_data, binding, grid_shape, grid_cell):
        self.features = features
        self.flags = flags
        self.arrays = arrays
        self.collider_data = collider_data
        self.colliders = collider_data.colliders if collider_data is not None else None
        self.collider_order = collider_data.order if collider_data is not None else None
        self.binding = binding
        self.grid_shape = grid_shape
        self.grid_cell = grid_cell

    def bytes_per_particle(self, precision: str) -> float:
        """Device bytes per particle of the features' per-particle arrays (model and scratch)."""
        f = np.dtype(precision).itemsize
        b = 0
        if self.collider_data is not None:
            b += f
        if velocity_pass_flags(self.flags)[0]:
            b += 3 * f      # the velocity pass's output (DFTL's; the elastic step's is 4 words)
        return b

    def bytes_per_strand(self, precision: str) -> float:
        f = np.dtype(precision).itemsize
        b = 0
        if "drag" in self.flags:
            b += f
        if self.binding is not None:
            b += 12 + 3 * f
        return b

    def grid_bytes(self, precision: str) -> int:
        if self.grid_shape is None:
            return 0
        hh = find(self.features, HairHair)
        words = 5 if hh is not None and hh.splat_interval > 1 else 4   # + the momentum's own density
        return int(np.prod(self.grid_shape)) * words * np.dtype(precision).itemsize


def build(model_args, features, *, widths=None) -> ModelFeatures:
    """Device data for ``features`` of a model being built (``model_args``: the Model's fields:
    device, precision, layout, scalar, vec3, counts, points (world, input order), origin)."""
    features = check_features(features)
    flags = feature_flags(features)
    ctx = dict(model_args, ftype=numpy_type(model_args["precision"]))
    arrays = {}
    collider_data = None
    found = find(features, Colliders)
    if found is not None and found.shapes:
        collider_data = colliders.build(found, ctx, widths)
    drag = find(features, Drag)
    if drag is not None:
        arrays["drag"] = air.build_drag(drag, len(ctx["counts"]), ctx["layout"].strand_order, ctx["scalar"],
                                        ctx["ftype"], ctx["device"])
    rb = find(features, RootBinding)
    bound = binding.build(rb, ctx) if rb is not None else None
    grid_shape = grid_cell = None
    hh = find(features, HairHair)
    if hh is not None:
        grid_shape, grid_cell = hair_hair.grid_dimensions(hh, ctx["points"], ctx["counts"])
    return ModelFeatures(features, flags, arrays, collider_data, bound, grid_shape, grid_cell)


class FeatureControl(AbsentFeatures):
    """Per-frame animated data of the features (``control.features``), device coordinates:
    collider poses (``colliders``: :class:`~dftl_warp.features.colliders.ColliderControl`), the
    wind (``air``: :class:`~dftl_warp.features.air.WindControl`), the root-binding mesh
    (``binding``: :class:`~dftl_warp.features.binding.BindingControl`); each None when absent,
    and then answered as a model without features answers
    (:class:`~dftl_warp.core.state.AbsentFeatures`).

    Collider poses move from ``start`` to ``end`` across a frame like the roots; the current and
    previous substep's poses (``pose``, ``pose_prev``, and their inverses) are updated by each step.
    It never writes the Control: the bound roots go back to the caller
    (:meth:`~dftl_warp.core.state.Control.bind_roots`).
    """

    def __init__(self, model):
        self.model = model
        mf = model.feature_data
        self.colliders = colliders.ColliderControl(model, mf.collider_data) if mf.collider_data is not None else None
        #: the Wind feature, or None
        self.wind = find(mf.features, Wind)
        self.air = air.WindControl(self.wind, model) if self.wind is not None else None
        self.binding = binding.BindingControl(model, mf.binding) if mf.binding is not None else None

    # -- colliders -----------------------------------------------------------------------------

    def _collider(self, name):
        return None if self.colliders is None else getattr(self.colliders, name)

    pose_start = property(lambda self: self._collider("pose_start"))
    pose_end = property(lambda self: self._collider("pose_end"))
    pose = property(lambda self: self._collider("pose"))
    pose_prev = property(lambda self: self._collider("pose_prev"))
    inv_pose = property(lambda self: self._collider("inv_pose"))
    inv_pose_prev = property(lambda self: self._collider("inv_pose_prev"))

    def set_collider_poses(self, start, end=None, **rates) -> None:
        """Poses of all colliders for this frame: (C, 7) rows ``(px, py, pz, qx, qy, qz, qw)``,
        world space (m), in the Colliders' order; ``end`` defaults to ``start``. ``rate_start``,
        ``rate_end`` (the rows' time derivatives) and ``frame_duration`` (s) put them on the roots'
        C1 path inside the frame
        (:meth:`ColliderControl.set_poses <dftl_warp.features.colliders.ColliderControl.set_poses>`)."""
        if self.colliders is None:
            return super().set_collider_poses(start, end, **rates)
        self.colliders.set_poses(start, end, **rates)

    def resync(self) -> None:
        """Forget the colliders' previous pose (after restoring a saved state): the next
        :meth:`set_collider_poses` places them at its start without sweeping."""
        if self.colliders is not None:
            self.colliders.resync()

    def set_mesh_points(self, index: int, points, start=None) -> None:
        """Local points (P, 3), m, of mesh collider ``index`` (Colliders order) at the coming frame's
        end, set once a frame before its substeps: the mesh moves to them through the frame (from
        ``start`` when given, else from the points last set;
        :meth:`ColliderControl.set_mesh_points <dftl_warp.features.colliders.ColliderControl.set_mesh_points>`)."""
        if self.colliders is None:
            return super().set_mesh_points(index, points)
        self.colliders.set_mesh_points(index, points, start=start)

    def graph_variant(self) -> tuple:
        """What a frame's CUDA graph depends on beyond its inputs (the meshes moving per substep)."""
        return () if self.colliders is None else self.colliders.graph_variant()

    # -- wind ----------------------------------------------------------------------------------

    @property
    def wind_velocity(self):
        return None if self.air is None else self.air.velocity

    @property
    def wind_time(self):
        return None if self.air is None else self.air.time

    def set_frame_time(self, start: float, end: float) -> None:
        """The frame spans ``start`` -> ``end`` seconds: wind velocity from its keyframes, noise time.
        ValueError unless both are finite numbers of seconds and ``end`` is not before ``start``;
        without a Wind feature nothing else (:class:`~dftl_warp.core.state.AbsentFeatures`)."""
        super().set_frame_time(start, end)
        if self.air is not None:
            self.air.set_frame_time(start, end)

    def set_wind(self, start, end=None) -> None:
        """Wind velocity (3,) m/s at frame start and end (overrides the keyframes for this frame)."""
        if self.air is None:
            return super().set_wind(start, end)
        self.air.set_wind(start, end)

    # -- roots on a deforming mesh -------------------------------------------------------------

    def bound_roots(self, start, end=None) -> tuple:
        """The bound roots (device strand order, m relative to ``model.origin``) at frame start and
        end from the root-binding mesh's world points (P, 3) then; the caller sets them as root
        targets (:meth:`~dftl_warp.core.state.Control.bind_roots` does both)."""
        if self.binding is None:
            return super().bound_roots(start, end)
        return self.binding.bound_roots(start, end)


class FeatureStep:
    """One featured step: collider poses, hair-hair grid, then the specialized sweep.

    ``kernel`` is the sweep, built for :attr:`sweep_flags`. With ``velocity_form`` (``"velocity"``
    for DFTL, ``"acceleration"`` for the elastic step, whose arithmetic is ``real``) the velocity
    features (:attr:`pass_flags`: hair-hair, drag, wind) run first in their own pass
    (:meth:`velocity_pass`, ``kernels/features/air_grid.py``) into :attr:`pass_output`, which the
    sweep reads; without it every feature is in the sweep."""

    def __init__(self, model, kernel, velocity_form: str | None = None, real=None):
        self.model = model
        self.kernel = kernel
        mf = model.feature_data
        self.flags = mf.flags
        self.pass_flags, self.sweep_flags = (velocity_pass_flags(self.flags) if velocity_form
                                             else (frozenset(), self.flags))
        self.velocity_form = velocity_form if self.pass_flags else None
        self._pass_kernel = None
        #: the velocity pass's output (velocities, or (a, c) in the acceleration form), or None
        self.pass_output = None
        if self.velocity_form is not None:
            real = model.scalar if real is None else real
            self._pass_kernel = velocity_features_kernel(model.scalar, real, self.pass_flags, self.velocity_form)
            dtype = model.vec3 if self.velocity_form == "velocity" else wp.types.vector(4, real)
            self.pass_output = wp.zeros(model.num_slots, dtype=dtype, device=model.device)
            self._pass_dummy = wp.zeros(1, dtype=wp.types.vector(4, real) if self.velocity_form == "velocity"
                                        else model.vec3, device=model.device)
            self._pass_blocks = blocks_per_strand(int(model.layout.strand_count.max()) if model.num_strands else 0)
        self._structs = {}
        self._grid = None
        if "hair_hair" in self.flags:
            self._grid = hair_hair.Grid(model, mf.grid_shape, mf.grid_cell)
        #: the hair-hair grid's arrays (lower, density, momentum), or None
        self.grid = None if self._grid is None else self._grid.arrays

    def kernels(self):
        """Every kernel a step launches (to load before a CUDA graph capture)."""
        ks = [self.kernel]
        if self._pass_kernel is not None:
            ks.append(self._pass_kernel)
        if self.model.feature_data.collider_data is not None:
            ks.append(collider_pose_kernel(self.model.scalar))
            if "meshes" in self.flags:
                ks.append(mesh_substep_kernel(self.model.scalar))
        if self._grid is not None:
            ks += self._grid.kernels()
        return ks

    def _struct(self, control, flags=None):
        """The feature struct of ``flags`` (default: the sweep's) for ``control``, cached per control."""
        flags = self.sweep_flags if flags is None else flags
        key = (id(control), flags)
        cached = self._structs.get(key)
        if cached is not None and cached[0] is control:
            return cached[1]
        m = self.model
        mf = m.feature_data
        fc = control.features
        if not flags:
            st = None
        else:
            st = feature_struct(m.scalar, flags)()
            if fc.colliders is not None and flags & set(collider_flags()):
                fc.colliders.fill_struct(st)
            air.fill_struct(st, flags, mf.arrays.get("drag"), fc.air)
            if self._grid is not None and "hair_hair" in flags:
                self._grid.fill_struct(st, find(mf.features, HairHair))
        self._structs[key] = (control, st)
        return st

    def launch(self, state_in, state_out, control, dt, root_alpha, head_inputs):
        self.prepare(state_in, control, dt, root_alpha)
        self.sweep(state_in, state_out, control, head_inputs)

    def prepare(self, state_in, control, dt, root_alpha) -> None:
        """Everything a step's sweep reads besides the State: this substep's collider poses, and
        the hair-hair grid's bounds and splat every ``splat_interval``-th substep of a frame."""
        self.pose_and_bounds(state_in, control, root_alpha, grid=False)
        if self._grid is not None:
            self._grid.rebuild(state_in.positions, state_in.velocities, dt, root_alpha)

    # the phases of :meth:`launch`; a split groom (dftl_warp.simulation.multi_device) combines its parts'
    # grids between them

    def pose_and_bounds(self, state_in, control, root_alpha, grid: bool = True) -> None:
        """This substep's collider poses; the grid's lower corner from this model's particles
        (``grid=False``: the poses only)."""
        if control.features is None:
            raise ValueError("this control was made before the model had features; use model.control()")
        fc = control.features
        if fc.colliders is not None:
            fc.colliders.advance(root_alpha)
        if grid and self._grid is not None:
            self._grid.bounds(state_in.positions)

    def grid_due(self, root_alpha) -> bool:
        """Whether the substep ending at root fraction ``root_alpha`` rebuilds the hair-hair grid
        (counts the substep: call it once a substep; :meth:`Grid.due`)."""
        return self._grid is not None and self._grid.due(root_alpha)

    def splat(self, state_in, dt: float = 0.0) -> None:
        """Density and momentum of this model's particles onto the grid (from ``lower``), each
        particle the rebuild's lead ahead along its velocity for substeps of ``dt`` (s) (into the
        grid's ``mass`` where it keeps one: :meth:`splat_density` writes ``density``)."""
        if self._grid is not None:
            self._grid.splat(state_in.positions, state_in.velocities, self._grid.lead(dt))

    def splat_density(self, state_in) -> None:
        """The density alone of this model's particles onto ``density``, in the substeps of a grid
        rebuilt every few (``splat_interval`` > 1; nothing otherwise)."""
        if self._grid is not None and self._grid.interval > 1:
            self._grid.splat_density(state_in.positions)

    def velocity_pass(self, state_in, control, dt, root_alpha, drag: float = 0.0) -> None:
        """Hair-hair, drag and wind of every free particle of ``state_in`` into :attr:`pass_output`
        (after the grid's splat; ``drag``: the elastic solver's own, 1/s)."""
        m = self.model
        velocities = self.pass_output if self.velocity_form == "velocity" else self._pass_dummy
        accelerations = self._pass_dummy if self.velocity_form == "velocity" else self.pass_output
        wp.launch(self._pass_kernel, dim=(self._pass_blocks, m.num_strands), device=m.device,
                  inputs=[m.strand_base, m.strand_stride, m.strand_count, float(root_alpha), float(dt), float(drag),
                          self._struct(control, self.pass_flags), state_in.positions, state_in.velocities],
                  outputs=[velocities, accelerations])

    def sweep(self, state_in, state_out, control, head_inputs) -> None:
        """The featured sweep of every strand (reading the grid, if any): with the velocity pass,
        the pass then the sweep of the colliders (or the bare step) from its velocities."""
        velocities = state_in.velocities
        if self.velocity_form is not None:
            self.velocity_pass(state_in, control, head_inputs[HEAD_DT], head_inputs[HEAD_ROOT_ALPHA])
            velocities = self.pass_output
        if not self.sweep_flags:
            # the bare step: no feature struct, corrections only in the prior form
            prior = any(a.label == "corrections_in" for a in self.kernel.adj.args)
            wp.launch(self.kernel, dim=self.model.num_strands, device=self.model.device, block_dim=SWEEP_BLOCK_DIM,
                      inputs=[*head_inputs, state_in.positions, velocities,
                              *([state_in.corrections] if prior else [])],
                      outputs=[state_out.positions, state_out.velocities, *([state_out.corrections] if prior else [])])
            return
        st = self._struct(control)
        wp.launch(self.kernel, dim=self.model.num_strands, device=self.model.device, block_dim=SWEEP_BLOCK_DIM,
                  inputs=[*head_inputs, st, state_in.positions, velocities, state_in.corrections],
                  outputs=[state_out.positions, state_out.velocities, state_out.corrections])


def memory_estimate(model, correction: str = "prior") -> dict:
    """Device bytes the simulation of ``model`` holds: per strand (mean, strands of the model's
    sizes), split into the bare solver's and the features', plus fixed-size feature memory.

    Counts the State (positions, velocities, and corrections in the prior form), the Model's
    rest lengths and strand tables, the Control's root targets, and the features' arrays.
    """
    f = np.dtype(model.precision).itemsize
    points = model.num_points
    strands = max(model.num_strands, 1)
    vectors = 3 if correction == "prior" else 2
    bare = points * (vectors * 3 * f + f) + model.num_strands * (3 * 4 + 3 * 3 * f)
    mf = model.feature_data
    feature = 0
    fixed = 0
    if mf is not None:
        feature = points * mf.bytes_per_particle(model.precision) + model.num_strands * mf.bytes_per_strand(
            model.precision)
        fixed = mf.grid_bytes(model.precision)
        if mf.collider_data is not None:
            fixed += colliders.fixed_bytes(mf.collider_data, model.precision)
    return {
        "bare_bytes_per_strand": bare / strands,
        "feature_bytes_per_strand": feature / strands,
        "bytes_per_strand": (bare + feature) / strands,
        "fixed_feature_bytes": fixed,
    }
