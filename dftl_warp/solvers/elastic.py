"""The elastic-rod solver (``solver="elastic"``, opt-in): inextensible Kirchhoff-type strands with
bending, twist-coupled material frames and a clamped root, stepped by *scheme K*.

One step (kernel: :mod:`dftl_warp.kernels.solvers.elastic`; rest data: :mod:`.elastic_rest`):

1. frames: one projective-dynamics Gauss-Seidel sweep root -> tip (each frame exactly minimises the
   bending + twist energy given its neighbours);
2. velocities: a linearly implicit (backward Euler) solve with implicit bending ``h^2 K`` and the
   exact linearised inextensibility constraint, a banded 4x4-block KKT system per strand;
3. follow-the-leader projection of ``x + h v`` (segment lengths exact to round-off), velocities
   ``(x^{n+1} - x^n)/h`` with DFTL's correction ``s`` (``damping``) in the prior or posterior form.

Statics are exact and independent of the substep count: at a fixed point the KKT system is the
discrete equilibrium ``f + J^T lambda = 0``. With ``inverse_statics`` (default) the authored shape
is that equilibrium under the solver's gravity, so a styled groom does not sag.

**The clamp.** The first segment leaves the root along its authored direction: a kinematic *ghost*
point sits one segment behind the root. By default the ghosts move with the roots' translation
(``Control.set_root_targets``); :meth:`ElasticSolver.set_clamp_targets` sets them per frame (world
positions, input strand order), so a caller that moves roots and ghosts by the same rigid transform
gets a rotating clamp. :attr:`ElasticSolver.authored_clamps` gives the authored ghosts (world).

**Units.** Options are in the units of the model: SI (m, kg, s, Pa) for grooms in metres. For a USD
stage in stage units of ``u = metersPerUnit`` metres, pass lengths (``radius``) in stage units
(``r_stage = r_m / u``), ``density`` in kg per stage-unit^3 (``rho_m * u^3``) and the moduli in
kg / (stage-unit s^2) (``E_Pa * u``), gravity in stage-units/s^2; the motion is then identical.

**State.** :class:`ElasticState` adds to the State, per particle, the tensions of the last step
(``T``, for the implicit string stiffness), the material frames (unit quaternions x, y, z, w; one
per bending vertex, identity at rest) and, per device strand, the clamp ghost's last position.
All of it survives between frames and is cloned/assigned with the State. The factorisation
scratch (``Di``, ``U`` 4x4 and ``w`` 4 per particle, in the computation precision) is solver-held
and per step only.

**Twist modulus.** ``twist_modulus`` defaults to :data:`TWIST_G` = 10 x hair's shear modulus
(0.89 GPa, Robbins 2002): with the physical value the inverse-statics equilibrium of a styled
helix is a saddle (measured in the prototype, ``/work/scratch/rods2/README.md``); 10x is close to
the twist-free (Bishop) limit. It is a modelling choice, not measured hair torsion; the couplings
are also raised automatically where inverse statics needs it (:mod:`.elastic_rest`).

**Precision.** The State is stored in the model's precision; the kernel computes in float64 by
default (``compute_precision``). In float32 arithmetic the cantilever statics (within 3e-6 L of
float64) and the zero-gravity curly strand (2e-6 L in 10 s) pass, but a styled strand under gravity
with inverse statics moves 3e-2 L (its bending forces balance gravity only to float32 round-off);
with float64 arithmetic and float32 storage it moves 2e-8 L.

**Features.** Colliders (every registered shape, their per-substep poses from the Control's
``features``) respond as in the featured DFTL sweep, after the follow-the-leader projection:
rounds of collide (the first continuous, Coulomb friction) then back to the rest length from the
leader. Contact moves the position only: the velocity is ``(x^{n+1} - x^n)/h`` of the contact
position, the tensions are the solve's and the correction ``c`` the projection's (as DFTL's). The
Drag feature (per strand, added to ``drag``) and Wind (with its curl noise) act in the implicit
solve, as a force ``m drag (w - v^{n+1})``. Hair-hair (:class:`~dftl_warp.features.HairHair`, its
grid splatted every ``splat_interval`` substeps as for DFTL) acts in the same solve: friction as the
force ``m c (v_grid - v^{n+1})`` (c = ``friction``, 1/s, implicit like drag) and repulsion as the
explicit force ``-m repulsion h_grid grad(rho)`` sampled at ``x^n``. Roots bound to a deforming
mesh (:class:`~dftl_warp.features.RootBinding`) take their clamp from it: :meth:`ElasticSolver.bind_clamps`
turns each authored ghost with its bound triangle's frame. Other features are refused by name
(:func:`check_features`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from ..core.model import DEFAULT_HAIR_WIDTH
from ..core.precision import numpy_type, scalar_type
from ..core.state import State
from ..kernels.solvers.elastic import NoFeatures, elastic_flags, elastic_step_kernels
from . import elastic_rest
from .elastic_energy import ElasticEnergy
from .base import DEFAULT_GRAVITY, Solver, check_bool, check_damping, check_gravity, check_real, register

#: human hair: Young's modulus (Pa), shear modulus (Pa), density (kg/m^3) (Robbins 2002)
HAIR_E = 3.89e9
HAIR_G = 0.89e9
HAIR_DENSITY = 1320.0
#: default twist-coupling modulus: 10 x HAIR_G (see the module docstring)
TWIST_G = 10 * HAIR_G
#: default hair radius (m) when the model has no widths
DEFAULT_RADIUS = 0.5 * DEFAULT_HAIR_WIDTH


#: CUDA threads per block of the elastic step (H200, the 1M production scene: blocks of 128 measured
#: 37.1 ms a step against 34.4 with 256, docs/benchmarks.md; ``scripts/profile_features.py
#: --block-dims`` measures others)
ELASTIC_BLOCK_DIM = 256

def check_features(model) -> None:
    """ValueError naming the model's features the elastic solver does not support (it supports
    colliders, drag, wind, hair-hair and root binding)."""
    from ..features import Colliders, Drag, HairHair, RootBinding, Wind

    bad = [f for f in model.features if not isinstance(f, (Colliders, Drag, HairHair, RootBinding, Wind))]
    names = [type(f).__name__ for f in bad]
    flags = set(model.feature_flags) - elastic_flags()
    names += [f"the {flag!r} flag" for flag in sorted(flags)
              if not any(flag in getattr(f, "flags", ()) for f in bad)]
    if names:
        raise ValueError("the elastic solver supports colliders, drag, wind, hair-hair and root binding only; it does not "
                         f"support these features: {'; '.join(names)}")


@dataclass(eq=False)
class ElasticState(State):
    """A State with the elastic solver's extra arrays: ``tensions`` (per particle, model precision),
    ``frames`` (per particle, quaternions; the tip's is unused) and ``clamps`` (per device strand,
    the clamp ghost's position relative to the model origin)."""

    tensions: wp.array | None = None
    frames: wp.array | None = None
    clamps: wp.array | None = None

    def clone(self) -> ElasticState:
        base = State.clone(self)
        return ElasticState(positions=base.positions, velocities=base.velocities, corrections=base.corrections,
                            storage=base.storage, layout=base.layout, tensions=wp.clone(self.tensions),
                            frames=wp.clone(self.frames), clamps=wp.clone(self.clamps))

    def assign(self, other: State) -> None:
        State.assign(self, other)
        if isinstance(other, ElasticState):
            wp.copy(self.tensions, other.tensions)
            wp.copy(self.frames, other.frames)
            wp.copy(self.clamps, other.clamps)


def _rest_rows(rest_shape, npts: int) -> np.ndarray:
    """``rest_shape`` as float64 rows of 3; ValueError naming it for what is not numbers in rows of 3."""
    try:
        return np.asarray(rest_shape, dtype=np.float64).reshape(-1, 3)
    except (TypeError, ValueError):
        raise ValueError(f"rest_shape must be {npts} finite points (one per model point), got {rest_shape!r}") from None


def _per_point(name: str, value, npts: int) -> np.ndarray:
    """``value`` (one number or one per point) as a (npts,) float array; ValueError naming ``name``
    for another length or a non-numeric value."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be one number or one per point ({npts}), got {value!r}") from None
    arr = arr.reshape(-1)
    if arr.shape[0] == 1:
        return np.full(npts, float(arr[0]))
    if arr.shape[0] != npts:
        raise ValueError(f"{name} must be one number or one per point ({npts}), got {arr.shape[0]} values")
    return arr.astype(float)


@register
class ElasticSolver(ElasticEnergy, Solver):
    """Elastic rods, scheme K (see the module docstring).

    Args:
        model: the :class:`~dftl_warp.core.model.Model` (its features: colliders, drag, wind, hair-hair
            and root binding, :func:`check_features`); free particles need non-zero rest lengths.
        youngs_modulus: E (Pa, or the model's units), default human hair 3.89e9.
        density: kg/m^3, default 1320.
        radius: hair radius, one value or one per point (input order); default half the model's
            ``widths`` where it has them, else 40e-6.
        twist_modulus: the frame chain's twist modulus (default :data:`TWIST_G`).
        inverse_statics: the authored shape is the equilibrium under ``gravity`` (default True).
        damping: DFTL's ``s`` in [0, 1] (default 1: the share of the follow-the-leader correction
            removed from the velocities; with s < 1 the error against the constrained dynamics stops
            falling with the step, docs/elastic/convergence.md).
        correction: ``"prior"`` or ``"posterior"``.
        drag: linear drag (1/s), implicit; 0 by default.
        gravity: acceleration (3,).
        compute_precision: ``"float32"``/``"float64"``: the kernel's arithmetic (the State stays in the
            model's precision); default float64 (see :attr:`compute_precision`'s note in ``__init__``).
        stiffness_scale: a factor on the bending stiffness E*I, one value or one per point (input
            order), >= 0 (a stiffness ramp; ``primvars:dftl:bendStiffnessScale`` in USD); default 1.
            0 is a hinge: no bending at that vertex (all 0: a chain that only keeps its lengths);
            inverse statics cannot hold a bend the authored shape needs there
            (:meth:`unheld_vertices`).
        rest_shape: the rest shape (world positions, (P, 3), input order; ``physics:restShapePoints``
            in USD); default the model's points. Each strand's rest shape is moved so that its root
            sits on the model's root; its segment lengths become the strand's lengths.
    """

    name = "elastic"
    options = ("youngs_modulus", "density", "radius", "twist_modulus", "inverse_statics", "damping", "correction",
               "drag", "compute_precision", "stiffness_scale", "rest_shape")

    def __init__(self, model, *, gravity=DEFAULT_GRAVITY, youngs_modulus: float = HAIR_E,
                 density: float = HAIR_DENSITY, radius=None, twist_modulus: float = TWIST_G,
                 inverse_statics: bool = True, damping: float = 1.0, correction: str = "prior",
                 drag: float = 0.0, compute_precision: str | None = None, stiffness_scale=None,
                 rest_shape=None):
        check_features(model)
        inverse_statics = check_bool("inverse_statics", inverse_statics)
        if correction not in ("prior", "posterior"):
            raise ValueError(f"unknown correction {correction!r}; choose prior or posterior")
        check_damping(damping)   # "0.5" and True were taken through float()
        for label, value in (("youngs_modulus", youngs_modulus), ("density", density),
                             ("twist_modulus", twist_modulus)):
            check_real(label, value)
        check_real("drag", drag, inclusive=True)
        if model.layout.slot_of_point is None or model.rest_positions is None:
            raise ValueError("the elastic solver needs a model with host rest positions")
        super().__init__(model, gravity=gravity)
        self.gravity64 = check_gravity(gravity)
        self.damping = float(damping)
        self.correction = correction
        self.drag = float(drag)
        self.youngs_modulus = float(youngs_modulus)
        self.density = float(density)
        self.twist_modulus = float(twist_modulus)
        self.inverse_statics = bool(inverse_statics)
        if compute_precision not in (None, "float32", "float64"):
            raise ValueError(f"compute_precision must be float32 or float64, got {compute_precision!r}")
        # float32 computation passes statics and zero-gravity stillness but not inverse statics under
        # gravity (a styled helix moves 3e-2 L: the bending forces cancel gravity to float32 round-off);
        # float64 inside with float32 storage keeps it within 2e-8 L (measured, tests/test_elastic.py)
        self.compute_precision = compute_precision or "float64"
        self.real = scalar_type(self.compute_precision)
        real = self.real
        dev, lay = model.device, model.layout
        npts = model.num_points
        source = "radius"
        if radius is None:
            source = "half the model's widths" if model.widths is not None else source
            radius = 0.5 * model.widths if model.widths is not None else DEFAULT_RADIUS
        radius = _per_point("radius", radius, npts)
        bad = ~(np.isfinite(radius) & (radius > 0))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            hint = " (widths of 0, e.g. tapered tips: pass radius=)" if source != "radius" else ""
            raise ValueError(f"radius[{i}] = {float(radius[i])!r} ({source}, point {i}): must be finite and > 0{hint}")
        self.radius = radius
        scale = np.ones(npts) if stiffness_scale is None else _per_point("stiffness_scale", stiffness_scale, npts)
        bad = ~(np.isfinite(scale) & (scale >= 0))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"stiffness_scale[{i}] = {float(scale[i])!r}: must be finite and >= 0 "
                             "(0: no bending there)")
        self.stiffness_scale = scale
        points = model.rest_positions[lay.slot_of_point].astype(np.float64)   # device coordinates
        if rest_shape is not None:
            rest = _rest_rows(rest_shape, npts)
            if rest.shape[0] != npts or not np.isfinite(rest).all():
                raise ValueError(f"rest_shape must be {npts} finite points (one per model point)")
            starts = elastic_rest.strand_offsets(model.counts)
            shift = np.repeat(points[starts] - (rest[starts] - np.asarray(model.origin, float)), model.counts, axis=0)
            points = rest - np.asarray(model.origin, float) + shift
        #: the rest shape: device coordinates, input order (float64)
        self._rest_points = points
        self._build_rest(points)
        self._clamp_start = wp.clone(self._clamp_offset)
        self._clamp_end = wp.clone(self._clamp_offset)
        #: the ghosts' path deviations (``T v - chord``, Control's form), zero on a linear path
        self._clamp_deviation_start = wp.zeros_like(self._clamp_offset)
        self._clamp_deviation_end = wp.zeros_like(self._clamp_offset)
        self._clamp_relative = 1
        #: the clamps' rotations from their authored poses at the frame's start and end (the root
        #: frame's twist about the first segment; identity: the minimal rotation onto the ghost)
        mat33s = wp.types.matrix((3, 3), model.scalar)
        self._identity_rotations = np.tile(np.eye(3, dtype=numpy_type(model.precision)), (model.num_strands, 1, 1))
        self._clamp_rotation_start = wp.array(self._identity_rotations, dtype=mat33s, device=dev)
        self._clamp_rotation_end = wp.array(self._identity_rotations, dtype=mat33s, device=dev)
        self._gravity_real = wp.types.vector(3, real)(*self.gravity64)
        n = model.num_slots
        self._scratch = [wp.zeros(n, dtype=wp.types.vector(10, real), device=dev),
                         wp.zeros(n, dtype=wp.types.matrix((3, 4), real), device=dev),
                         wp.zeros(n, dtype=wp.types.vector(4, real), device=dev)]
        self._dummy = wp.zeros(1, dtype=model.vec3, device=dev)
        flags = model.feature_flags
        cuda = wp.get_device(dev).is_cuda
        #: the step's kernels, launched in order with the same arguments (its sweeps, one each on CUDA)
        self._kernels = elastic_step_kernels(model.scalar, real, correction, frozenset(), False, cuda)
        #: the featured DFTL step's host side (collider poses per substep, the feature struct, the
        #: velocity pass of hair-hair, drag and wind: ``kernels/features/air_grid.py``)
        self._features = None
        self._no_features = NoFeatures()
        self._no_accelerations = wp.zeros(1, dtype=wp.types.vector(4, real), device=dev)
        if flags:
            from ..features.step import FeatureStep, velocity_pass_flags

            pass_flags, sweep_flags = velocity_pass_flags(flags)
            self._kernels = elastic_step_kernels(model.scalar, real, correction, sweep_flags, bool(pass_flags), cuda)
            self._features = FeatureStep(model, self._kernels[0], velocity_form="acceleration" if pass_flags else None,
                                         real=real)

    def _build_rest(self, points) -> None:
        """The rest data of the rest shape ``points`` (device coordinates, input order, float64): the
        kernel's model arrays, the clamp directions, ghosts and offsets, the inverse-statics tensions.
        Device arrays are made on the first call and overwritten in place after it, so a captured
        CUDA graph keeps reading them."""
        m, lay = self.model, self.model.layout
        fields, strands, self._groups = elastic_rest.build(
            points, m.counts, lay.slot_of_point, lay.strand_order, m.num_slots, self.radius,
            stiffness_scale=self.stiffness_scale,
            E=self.youngs_modulus, G=self.twist_modulus, rho=self.density, gravity=self.gravity64,
            inverse_statics=self.inverse_statics)
        rt, st = numpy_type(self.compute_precision), numpy_type(m.precision)
        self._rest_ghost = strands["ghost"]                                         # device order, float64
        self._rest_tension = strands["tension"].astype(st)
        host = {k: np.ascontiguousarray(v, dtype=rt) for k, v in fields.items()}
        direction = np.ascontiguousarray(strands["d0"], dtype=rt)
        offset = (self._rest_ghost - m.root_rest.numpy().astype(np.float64)).astype(st)
        if not hasattr(self, "_fields"):
            real, dev = self.real, m.device
            vec3r, quatr = wp.types.vector(3, real), wp.types.quaternion(real)
            self._fields = {k: wp.array(v, dtype=vec3r if k == "curvature" else quatr if k == "rest_rotation" else real,
                                        device=dev) for k, v in host.items()}
            self._clamp_direction = wp.array(direction, dtype=vec3r, device=dev)
            self._curved = wp.array(strands["curved"], dtype=wp.int32, device=dev)
            self._clamp_offset = wp.array(offset, dtype=m.vec3, device=dev)
            return
        for k, v in host.items():
            self._fields[k].assign(v)
        self._clamp_direction.assign(direction)
        self._curved.assign(strands["curved"])
        self._clamp_offset.assign(offset)

    def _strands_away(self, state, reference) -> np.ndarray:
        """Input indices of the strands of ``state`` with a particle more than a hundredth of its hair
        radius from ``reference`` (device coordinates, input order)."""
        m = self.model
        away = np.abs(m.points_from_device(state.positions, relative=False) - reference).max(axis=1)
        return np.unique(np.repeat(np.arange(m.num_strands), m.counts)[away > 1.0e-2 * self.radius])

    def moved_strands(self, state) -> np.ndarray:
        """Input indices of the strands of ``state`` moved from the model's points (by the clean
        start's push-out): compared with the points, not the rest shape, which ``rest_shape`` may put
        elsewhere."""
        m = self.model
        return self._strands_away(state, m.rest_positions[m.layout.slot_of_point])

    def unheld_vertices(self) -> tuple[np.ndarray, int]:
        """(input indices of the strands, number of vertices) where ``stiffness_scale`` is 0 but
        the authored shape needs a bending moment to stand still (inverse statics): those hinges
        bend under gravity from the first step (:meth:`RodGroup.rest_curvature
        <dftl_warp.solvers.elastic_rest.RodGroup.rest_curvature>`)."""
        strands = [idx[grp.unheld.any(axis=1)] for _, idx, grp in self._groups]
        vertices = sum(int(grp.unheld.sum()) for _, _, grp in self._groups)
        return np.sort(np.concatenate(strands + [np.zeros(0, np.int64)])), vertices

    def unstable_strands(self, **options):
        """Strands whose rest shape is an unstable equilibrium
        (:func:`~dftl_warp.solvers.elastic_stability.unstable_strands`, its ``options`` and returns)."""
        from .elastic_stability import unstable_strands

        return unstable_strands(self._groups, **options)

    def unchecked_strands(self) -> tuple[np.ndarray, int]:
        """(input indices of the strands :meth:`unstable_strands` never checks, too long for its
        budget: :func:`~dftl_warp.solvers.elastic_stability.too_long`; the most segments of a strand)."""
        from .elastic_stability import too_long

        return too_long(self._groups), max((grp.N for _, _, grp in self._groups), default=0)

    def adopt_rest_shape(self, state, strands=None) -> np.ndarray:
        """Make the positions of ``state`` the rest shape (with its inverse statics, clamp and rest
        tensions) of ``strands``: input strand indices, or by default every strand whose positions
        differ from its rest shape by more than a hundredth of its hair radius. The state's tensions,
        frames and clamp ghosts of those strands become the new rest values. Returns the input strand
        indices whose rest shape changed.

        For hair moved out of a collider before the first step
        (:func:`~dftl_warp.features.clean_start.resolve_start`): its authored shape lay inside, and as
        the rest shape it would press the strand back in at every step, which the contact, acting
        after the solve, answers by pushing it out again: a chatter of millimetres with a period of
        two substeps that never settles (docs/elastic.md, "Hair authored inside a collider")."""
        m, lay = self.model, self.model.layout
        strands = self._strands_away(state, self._rest_points) if strands is None else strands
        strands = np.asarray(strands, dtype=np.int64).reshape(-1)
        if strands.size == 0:
            return strands
        take = np.isin(np.repeat(np.arange(m.num_strands), m.counts), strands)
        points = self._rest_points.copy()
        points[take] = m.points_from_device(state.positions, relative=False)[take]   # device coordinates
        self._build_rest(points)
        self._rest_points = points
        if self._clamp_relative:
            wp.copy(self._clamp_start, self._clamp_offset)
            wp.copy(self._clamp_end, self._clamp_offset)
        slots = lay.slot_of_point[take]
        device_strands = np.flatnonzero(np.isin(lay.strand_order, strands))
        tensions, frames, clamps = state.tensions.numpy(), state.frames.numpy(), state.clamps.numpy()
        tensions[slots] = self._rest_tension[slots]
        frames[slots] = (0.0, 0.0, 0.0, 1.0)
        clamps[device_strands] = self._rest_ghost[device_strands]
        state.tensions.assign(tensions)
        state.frames.assign(frames)
        state.clamps.assign(clamps)
        return strands

    # -- the State -------------------------------------------------------------------------------

    @staticmethod
    def carries(correction: str) -> bool:
        return correction == "prior"

    @property
    def carries_corrections(self) -> bool:
        return self.carries(self.correction)

    def state(self) -> ElasticState:
        """A rest State: authored positions, zero velocities, inverse-statics tensions, identity
        frames, the clamp ghosts at their authored places."""
        m = self.model
        base = m.state(with_corrections=self.carries_corrections)
        frames = np.zeros((m.num_slots, 4), dtype=numpy_type(m.precision))
        frames[:, 3] = 1.0
        return ElasticState(
            positions=base.positions, velocities=base.velocities, corrections=base.corrections, storage=base.storage,
            layout=base.layout, tensions=wp.array(self._rest_tension, dtype=m.scalar, device=m.device),
            frames=wp.array(frames, dtype=wp.types.quaternion(m.scalar), device=m.device),
            clamps=wp.array(self._rest_ghost.astype(numpy_type(m.precision)), dtype=m.vec3, device=m.device))

    @property
    def authored_clamps(self) -> np.ndarray:
        """The authored clamp ghosts (S, 3), world coordinates, input strand order."""
        out = np.zeros((self.model.num_strands, 3))
        out[self.model.layout.strand_order] = self._rest_ghost
        return out + self.model.origin

    def set_clamp_targets(self, start=None, end=None, *, velocity_start=None, velocity_end=None,
                          frame_duration: float | None = None, rotation_start=None, rotation_end=None) -> None:
        """Clamp ghosts of the frame: world positions (S, 3) in input strand order at frame start
        and end (``end`` defaults to ``start``). They move like the roots
        (:class:`~dftl_warp.core.state.Control`): linearly across the frame, or, given their
        velocities (S, 3; units/s) at the frame's start and end and ``frame_duration`` (s), on the
        C1 Hermite curve with those tangents. ``rotation_start``/``rotation_end`` (S, 3, 3; column
        vectors, ``end`` defaults to ``start``): each clamp's rotation from its authored pose then,
        which turns the root frame about the first segment too (a curl turns with a head turning
        about it); without them the root frame is the minimal rotation onto the ghost's direction.
        ``start=None`` returns to the default: the authored ghosts moved with the roots' translation
        (on the roots' path), not turned."""
        m = self.model
        if start is not None:   # checked first: a NaN row left the clamps half set before the error
            end = start if end is None else end
            device_start = m.roots_to_device(start, "clamp targets (start)")
            device_end = m.roots_to_device(end, "clamp targets (end)")
        self._clamp_deviation_start.zero_()
        self._clamp_deviation_end.zero_()
        self._set_clamp_rotations(rotation_start, rotation_end)
        if start is None:
            wp.copy(self._clamp_start, self._clamp_offset)
            self._clamp_relative = 1
            return
        self._clamp_start.assign(device_start)
        self._clamp_end.assign(device_end)
        self._clamp_relative = 0
        if velocity_start is None:
            if velocity_end is not None or frame_duration is not None:
                raise ValueError("clamp velocities: give velocity_start (and velocity_end, frame_duration) together")
            return
        if frame_duration is None or not np.isfinite(frame_duration) or float(frame_duration) <= 0:
            raise ValueError(f"clamp velocities need frame_duration, a finite number of seconds > 0, "
                             f"got {frame_duration!r}")
        velocity_end = velocity_start if velocity_end is None else velocity_end
        chord = device_end.astype(np.float64) - device_start.astype(np.float64)
        order = m.layout.strand_order
        for target, v in ((self._clamp_deviation_start, velocity_start), (self._clamp_deviation_end, velocity_end)):
            v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
            if v.shape[0] != m.num_strands or not np.isfinite(v).all():
                raise ValueError(f"clamp velocities must be {m.num_strands} finite (3,) rows, one per strand")
            target.assign((float(frame_duration) * v[order] - chord).astype(device_start.dtype))

    def clamp_target_arrays(self) -> dict:
        """The device arrays :meth:`set_clamp_targets` fills with its ghosts and rotations (per device
        strand: ``start``, ``end``, ``deviation_start``, ``deviation_end``, ``rotation_start``,
        ``rotation_end``), for a caller that computes them on the device (the simulation's
        transform-driven roots); the ghosts are then the targets, not the authored ones moved with the roots."""
        self._clamp_relative = 0
        return {"start": self._clamp_start, "end": self._clamp_end, "deviation_start": self._clamp_deviation_start,
                "deviation_end": self._clamp_deviation_end, "rotation_start": self._clamp_rotation_start,
                "rotation_end": self._clamp_rotation_end}

    def _set_clamp_rotations(self, start, end) -> None:
        m = self.model
        if start is None:
            if end is not None:
                raise ValueError("clamp rotations: give rotation_start (and rotation_end) together")
            self._clamp_rotation_start.assign(self._identity_rotations)
            self._clamp_rotation_end.assign(self._identity_rotations)
            return
        end = start if end is None else end
        order = m.layout.strand_order
        for target, r in ((self._clamp_rotation_start, start), (self._clamp_rotation_end, end)):
            r = np.asarray(r, dtype=np.float64)
            if r.shape != (m.num_strands, 3, 3) or not np.isfinite(r).all():
                raise ValueError(f"clamp rotations must be {m.num_strands} finite 3x3 matrices, one per strand")
            if np.abs(np.einsum("sji,sjk->sik", r, r) - np.eye(3)).max() > 1e-6 or (np.linalg.det(r) <= 0).any():
                raise ValueError("clamp rotations must be rotation matrices (orthonormal, determinant 1)")
            target.assign(r[order].astype(self._identity_rotations.dtype))

    def bind_clamps(self, control) -> None:
        """Clamp ghosts of the frame from ``control``'s root-binding mesh, after ``control.bind_roots``
        (:meth:`~dftl_warp.features.binding.BindingControl.bound_clamps`): each authored ghost turned
        by the rotation of its strand's bound triangle's frame (edge 0 and the normal) from the rest
        mesh, on the roots' path (C1 where the roots were given velocities). Computed on the device."""
        binding = None if control.features is None else control.features.binding
        if binding is None:
            raise ValueError("bind_clamps: the model has no RootBinding feature")
        binding.bound_clamps(self._clamp_offset, control.frame_duration, self._clamp_start, self._clamp_end,
                             self._clamp_deviation_start, self._clamp_deviation_end,
                             self._clamp_rotation_start, self._clamp_rotation_end)
        self._clamp_relative = 0

    # -- stepping --------------------------------------------------------------------------------

    def graph_variant(self) -> tuple:
        """The clamps' mode (ghosts relative to the roots, or targets of their own) is a scalar of the
        step's launch: a graph captured in one mode must not be replayed in the other (a preroll with
        the clamps relative, then a shot with device-side targets, replayed the preroll's on CUDA)."""
        return (self._clamp_relative,)

    def kernels(self) -> list:
        """Every kernel a step launches, once each (the features' list holds the step's own)."""
        ks = (self._features.kernels() if self._features is not None else []) + list(self._kernels)
        return list(dict.fromkeys(ks))

    def step(self, state_in, state_out, control, dt: float, root_alpha: float = 1.0) -> None:
        """Advance ``state_in`` by ``dt`` seconds into ``state_out`` (which may be ``state_in``)."""
        m = self.model
        if m.num_strands == 0:
            return
        for s in (state_in, state_out):
            if not isinstance(s, ElasticState) or s.frames is None:
                raise ValueError("the elastic solver needs its own States (solver.state())")
            if self.carries_corrections and s.corrections is None:
                raise ValueError("the prior correction form needs states with corrections (solver.state())")
        if self._features is not None:
            # this substep's collider poses and the hair-hair grid (rebuilt every splat_interval substeps)
            self._features.prepare(state_in, control, dt, root_alpha)
        self._launch(state_in, state_out, control, dt, root_alpha)

    def step_on_grid(self, state, control, dt: float, root_alpha: float) -> None:
        """:meth:`step` in place once this substep's collider poses and hair-hair grid are set (a
        groom split over devices builds the grid of all its parts first:
        :class:`~dftl_warp.simulation.multi_device.SplitSolver`)."""
        self._launch(state, state, control, dt, root_alpha)

    def _launch(self, state_in, state_out, control, dt: float, root_alpha: float) -> None:
        """The velocity pass (where the features need one) and the step's kernels."""
        m = self.model
        f = self._fields
        prior = self.carries_corrections
        if self._features is not None:
            features = self._features._struct(control) or self._no_features
            accelerations = self._no_accelerations
            if self._features.velocity_form is not None:
                self._features.velocity_pass(state_in, control, dt, root_alpha, drag=self.drag)
                accelerations = self._features.pass_output
        else:
            features = self._no_features
            accelerations = self._no_accelerations
        inputs = [
            m.strand_base, m.strand_stride, m.strand_count,
            f["length"], f["mass"], f["bend"], f["twist"], f["k0"], f["k1"], f["k2"], f["curvature"],
            f["rest_rotation"], self._clamp_direction, self._curved,
            control.root_start, control.root_end, control.root_deviation_start, control.root_deviation_end,
            self._clamp_start, self._clamp_end, self._clamp_deviation_start, self._clamp_deviation_end,
            self._clamp_rotation_start, self._clamp_rotation_end,
            self._clamp_relative,
            float(root_alpha), self._gravity_real, float(dt), self.damping, self.drag, features,
            state_in.positions, state_in.velocities, state_in.corrections if prior else self._dummy,
            state_in.tensions, state_in.frames, state_in.clamps,
            *self._scratch, accelerations,
        ]
        outputs = [state_out.positions, state_out.velocities, state_out.corrections if prior else self._dummy,
                   state_out.tensions, state_out.frames, state_out.clamps]
        for kernel in self._kernels:
            wp.launch(kernel, dim=m.num_strands, block_dim=ELASTIC_BLOCK_DIM, inputs=inputs, outputs=outputs,
                      device=m.device)
