"""The reference solver's elastic option: the ``elastic`` solver's bending energy in RATTLE.

``ReferenceSolver(model, elastic={...})`` (or ``elastic=True`` for human hair's defaults) integrates
the strands as the elastic solver models them (:mod:`.elastic`, :mod:`.elastic_rest`): the same
masses ``m_i = rho pi r_i^2 (l_i + l_{i+1}) / 2``, bending weights, rest curvatures (inverse statics
under the reference's gravity), twist couplings and clamp ghost, built by the same
:func:`.elastic_rest.build`. The keys are the elastic solver's material options
(:data:`ELASTIC_OPTIONS`, same defaults); the motion is the true constrained dynamics of that
energy, second order (RATTLE), with the frames at their minimiser for the current positions
(kernel: :mod:`dftl_warp.kernels.solvers.reference_elastic`). It is what the accuracy study
measures the elastic solver against.

**The step limit.** The bending force is explicit: velocity Verlet (RATTLE) is stable only while
``h omega_max < 2``, ``omega_max`` the highest angular frequency of the linearised bending,
``sqrt(lambda_max(M^-1 K))`` with ``K = D^T W D`` on the free particles (the constraints and the
frames only lower it). For a uniform strand of segments ``l`` it is about
``(4 / l^2) sqrt(EI / (rho A))``: 80 um hair (``sqrt(EI / (rho A))`` = 0.034 m^2/s) with 1.54 mm
segments (a 4.93 cm strand in 32) bends at up to 5.8e4 rad/s (9.2 kHz), so ``h`` < 3.5e-5 s, 1200
substeps per 24 fps frame; with 6.25 mm segments (0.2 m in 32), 73 (the limit goes as ``l^2``).
The lowest modes are far slower: the first bending mode of a 2.5 cm cantilever is at 31 Hz, of a
1 cm one at 190 Hz. The limit is sharp (measured on a cantilever and a helix: stable at 0.99 x the
limit, blown up at 1.01 x): :meth:`ElasticReference.check_step` refuses a step beyond it with a
ValueError naming both numbers and the substeps a 24 fps frame needs.

Memory: 272 bytes of float64 scratch per particle (the kernel's docstring) instead of the
reference's 96, plus 88 bytes of rest data per particle.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..core.layout import strand_offsets
from ..kernels.solvers.reference_elastic import rattle_elastic_kernel
from . import elastic_rest
from .base import check_bool, check_real
from .elastic import DEFAULT_RADIUS, HAIR_DENSITY, HAIR_E, TWIST_G, _rest_rows

#: the elastic solver's material options the ``elastic`` keyword takes (same names and defaults)
ELASTIC_OPTIONS = ("youngs_modulus", "density", "radius", "twist_modulus", "inverse_statics", "stiffness_scale",
                   "rest_shape")

#: velocity Verlet's stability limit on ``h omega_max``
STABILITY_LIMIT = 2.0


def _per_point(value, npts: int, label: str, *, positive: bool) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64).reshape(-1) if np.ndim(value) else np.asarray([float(value)])
    try:
        a = np.broadcast_to(a, (npts,)).astype(np.float64)
    except ValueError:
        raise ValueError(f"{label} must be one value or one per point ({npts}), got {a.size}") from None
    ok = np.isfinite(a) & ((a > 0) if positive else (a >= 0))
    if not ok.all():
        raise ValueError(f"{label} must be finite and {'> 0' if positive else '>= 0'} (point {int(np.argmin(ok))})")
    return a


def rest_points(model, rest_shape=None) -> np.ndarray:
    """(P, 3) float64 rest points in device coordinates, input order: the model's points, or
    ``rest_shape`` (world, input order) moved so that each strand's root sits on the model's
    (as the elastic solver's ``rest_shape``)."""
    points = model.rest_positions[model.layout.slot_of_point].astype(np.float64)
    if rest_shape is None:
        return points
    rest = _rest_rows(rest_shape, model.num_points)
    if rest.shape[0] != model.num_points or not np.isfinite(rest).all():
        raise ValueError(f"rest_shape must be {model.num_points} finite points (one per model point)")
    starts = strand_offsets(model.counts)
    origin = np.asarray(model.origin, dtype=np.float64)
    shift = np.repeat(points[starts] - (rest[starts] - origin), model.counts, axis=0)
    return rest - origin + shift


def bending_omega_max(groups, num_strands: int) -> np.ndarray:
    """Per input strand, the highest angular frequency (rad/s) of the linearised bending,
    ``sqrt(lambda_max(M^-1 K))``, ``K = D^T W D`` on the free particles (0 for strands of fewer
    than 3 particles... and for those without bending stiffness)."""
    out = np.zeros(num_strands)
    for n, strands, grp in groups:
        N = n - 1
        rows = np.arange(N)
        for lo in range(0, len(strands), max(1, 2_000_000 // (N * N))):
            sl = slice(lo, lo + max(1, 2_000_000 // (N * N)))
            S = grp.W[sl].shape[0]
            D = np.zeros((S, N, N + 1))                   # rows: (Dx)_j; columns: x_0 .. x_N
            D[:, rows, rows] = -(grp.alpha[sl] + grp.gamma[sl])
            D[:, rows, rows + 1] = grp.gamma[sl]
            D[:, rows[1:], rows[1:] - 1] = grp.alpha[sl][:, 1:]
            D = D[:, :, 1:]                               # the free particles
            K = np.einsum("sji,sj,sjk->sik", D, grp.W[sl], D)
            s = 1.0 / np.sqrt(grp.m[sl][:, 1:])
            lam = np.linalg.eigvalsh(K * s[:, :, None] * s[:, None, :])[:, -1]
            out[strands[sl]] = np.sqrt(np.maximum(lam, 0.0))
    return out


class ElasticReference:
    """The elastic rest data of a :class:`~dftl_warp.solvers.reference.ReferenceSolver` on the
    device (float64), its step limit, its kernel and its host-side energy."""

    def __init__(self, model, gravity, options, *, drag: float = 0.0, frame_tolerance: float = 1.0e-11,
                 frame_iterations: int = 30):
        options = {} if options is True else dict(options)
        unknown = sorted(set(options) - set(ELASTIC_OPTIONS))
        if unknown:
            raise ValueError(f"elastic: unknown option(s) {', '.join(unknown)}; choose from {', '.join(ELASTIC_OPTIONS)}")
        # strings, None and bools were taken through float() / bool()
        self.youngs_modulus = check_real("elastic: youngs_modulus", options.get("youngs_modulus", HAIR_E))
        self.density = check_real("elastic: density", options.get("density", HAIR_DENSITY))
        self.twist_modulus = check_real("elastic: twist_modulus", options.get("twist_modulus", TWIST_G))
        self.inverse_statics = check_bool("elastic: inverse_statics", options.get("inverse_statics", True))
        check_real("drag", drag, inclusive=True)
        if model.layout.slot_of_point is None or model.rest_positions is None:
            raise ValueError("the elastic reference needs a model with host rest positions")
        npts = model.num_points
        radius = options.get("radius")
        if radius is None:
            radius = 0.5 * model.widths if model.widths is not None else DEFAULT_RADIUS
        self.radius = _per_point(radius, npts, "elastic: radius", positive=True)
        scale = options.get("stiffness_scale")
        self.stiffness_scale = np.ones(npts) if scale is None else _per_point(
            scale, npts, "elastic: stiffness_scale", positive=False)
        self.gravity = np.asarray(gravity, dtype=np.float64).reshape(3)
        self.drag = float(drag)
        self.frame_tolerance = float(frame_tolerance)
        self.frame_iterations = int(frame_iterations)
        lay = model.layout
        self.model = model
        fields, strands, self.groups = elastic_rest.build(
            rest_points(model, options.get("rest_shape")), model.counts, lay.slot_of_point, lay.strand_order,
            model.num_slots, self.radius, stiffness_scale=self.stiffness_scale, E=self.youngs_modulus,
            G=self.twist_modulus, rho=self.density, gravity=self.gravity, inverse_statics=self.inverse_statics)
        inv_mass = np.zeros(model.num_slots)
        free = fields["mass"] > 0
        inv_mass[free] = 1.0 / fields["mass"][free]
        inv_mass[lay.slot_of_point[strand_offsets(model.counts)]] = 0.0    # kinematic roots
        dev = model.device
        f64 = lambda a, dt=wp.float64: wp.array(np.ascontiguousarray(a, dtype=np.float64), dtype=dt, device=dev)  # noqa: E731
        roots = model.root_rest.numpy().astype(np.float64)
        self.arrays = [f64(fields["length"]), f64(inv_mass), f64(fields["bend"]), f64(fields["twist"]),
                       f64(fields["curvature"], wp.vec3d), f64(fields["rest_rotation"], wp.quatd),
                       f64(strands["ghost"] - roots, wp.vec3d),
                       wp.array(strands["curved"], dtype=wp.int32, device=dev)]
        #: per input strand: the highest bending frequency (rad/s) and the step limit 2 / omega (s)
        self.omega = bending_omega_max(self.groups, model.num_strands)
        self.omega_max = float(self.omega.max()) if self.omega.size else 0.0
        n = model.num_slots
        self._vectors = [wp.zeros(n, dtype=wp.vec3d, device=dev) for _ in range(5)]
        self._scalars = [wp.zeros(n, dtype=wp.float64, device=dev) for _ in range(3)]
        self.frames = wp.zeros(n, dtype=wp.quatd, device=dev)
        self._block = wp.zeros(n, dtype=wp.mat33d, device=dev)
        self._block_rhs = wp.zeros(n, dtype=wp.vec3d, device=dev)
        self.frame_residual = wp.zeros(model.num_strands, dtype=wp.float64, device=dev)
        self.reset_frames()
        self.kernel = rattle_elastic_kernel(model.scalar)

    @property
    def step_limit(self) -> float:
        """The largest stable step (s): ``2 / omega_max`` (inf without bending stiffness)."""
        return STABILITY_LIMIT / self.omega_max if self.omega_max > 0 else math.inf

    def check_step(self, dt: float) -> None:
        """ValueError naming the numbers when ``dt`` (s) is beyond :attr:`step_limit`."""
        if dt > self.step_limit:
            worst = int(np.argmax(self.omega))
            frames = math.ceil(1.0 / (24.0 * self.step_limit))
            raise ValueError(
                f"dt = {dt:.3g} s is beyond the elastic reference's stability limit 2/omega_max = "
                f"{self.step_limit:.3g} s (omega_max = {self.omega_max:.4g} rad/s, the stiffest bending mode, strand "
                f"{worst}; the bending force is explicit): use at least {frames} substeps per 24 fps frame")

    def reset_frames(self) -> None:
        """The frames' warm start back to the identity (the rest frames)."""
        q = np.zeros((self.model.num_slots, 4))
        q[:, 3] = 1.0
        self.frames.assign(q)

    def launch(self, solver, state_in, state_out, control, dt, alpha_first, alpha_step, substeps) -> None:
        m = self.model
        wp.launch(
            self.kernel,
            dim=m.num_strands,
            inputs=[
                m.strand_base, m.strand_stride, m.strand_count, m.rest_lengths, *self.arrays,
                control.root_start, control.root_end, control.root_deviation_start, control.root_deviation_end,
                float(alpha_first), float(alpha_step), int(substeps),
                solver._gravity64, float(dt), self.drag, solver.tolerance, solver.accept, solver.max_iterations,
                self.frame_tolerance, self.frame_iterations,
                state_in.positions, state_in.velocities,
                *self._vectors, *self._scalars, self.frames, self._block, self._block_rhs,
            ],
            outputs=[solver._residual, self.frame_residual, state_out.positions, state_out.velocities],
            device=m.device,
        )

    def energy(self, state) -> float:
        """Kinetic + gravitational (from the strands hanging straight down from their roots) +
        elastic energy of all strands (J, or the model's units), float64 on the host, with the
        frames of the last call (at their minimiser for its final positions)."""
        m = self.model
        lay = m.layout
        x = m.points_from_device(state.positions, relative=False)
        v = m.points_from_device(state.velocities, relative=False)
        q = self.frames.numpy()[lay.slot_of_point]
        offsets = self.arrays[6].numpy()
        ghosts = np.zeros((m.num_strands, 3))
        ghosts[lay.strand_order] = offsets
        starts = strand_offsets(m.counts)
        total = 0.0
        for n, strands, grp in self.groups:
            idx = starts[strands][:, None] + np.arange(n)[None]
            F = elastic_rest.quat_to_mat(q[idx[:, :n - 1]])
            curved = grp.curved
            F[~curved] = np.eye(3)         # straight strands: no frames (b = 0), no twist energy
            G = grp.G
            grp.G = np.where(curved[:, None], G, 0.0)
            try:
                total += float(grp.energy(x[idx], v[idx], F, x[idx[:, 0]] + ghosts[strands], self.gravity).sum())
            finally:
                grp.G = G
        return total
