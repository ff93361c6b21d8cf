"""Per-frame QC stored in the cache, and ``--check`` gates (docs/caches.md).

Every written frame gets, per simulated prim, computed on the simulation device by one small
kernel per part (:mod:`dftl_warp.kernels.output.qc`):

| metric | attribute | meaning |
|---|---|---|
| ``stretch`` | ``dftl:qc:maxStretch`` | max over segments of abs(length / rest length - 1) |
| ``speed`` | ``dftl:qc:maxSpeed`` | max particle speed, world space, stage units / s |
| ``energy`` | ``dftl:qc:energy`` | sum over free particles of 0.5 v^2 - g . x (per unit mass, stage units^2 / s^2) |
| ``nan`` | ``dftl:qc:nanCount`` | particles with a non-finite position or velocity |
| ``penetration`` | ``dftl:qc:maxPenetration`` | max over particles (roots excepted) of max(0, radius - d) / radius |

Penetration: ``d`` is the particle's signed distance to the nearest collider surface at the frame's
pose and ``radius`` its hair radius (half its width, per vertex where widths are), which is also
the colliders' contact distance: 0 at or outside the contact distance (hair resting on a
collider), 0.01 when it is 1% of the hair radius beyond it, 1 with its centre on the surface.
Where a prim has no widths the colliders' contact distance is 0 and the depth below the surface is
given in units of the default hair radius (40 um in stage units:
:func:`~dftl_warp.solvers.elastic_material.default_radius`), with a note (:attr:`FrameQC.notes`).
0 without colliders. Meshes are measured to any depth (as the clean start measures them), not only
within their ``depth_band``. A second kernel per part with colliders
(:mod:`dftl_warp.kernels.output.penetration`) measures it with the colliders' own collide functions.

Maxima and counts are reduced with atomics (exact in any order); energy comes back per strand and
is summed on the host in strand order, so the QC is bitwise the same split over devices or not.

A writer stores them with :meth:`~dftl_warp.output.base.FrameWriter.write_qc` (USD: time samples
on ``/dftl_qc/<prim path with / as _>``, whose ``dftl:qc:prim`` names the prim).

``--check 'stretch<1e-3,speed<50'``: :func:`parse_gates`; :func:`check` raises :class:`QCError`
(exit status 3 from ``simulate``, a failed job in ``batch``) naming the first frame and prim that
breaks a gate.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import UserError

#: the depth band (stage units) of mesh colliders in the QC: any depth (the closest-point query's reach)
ANY_DEPTH = 1.0e30

#: metric -> USD attribute (the order ``--check`` and the docs list them)
ATTRIBUTES = {
    "stretch": "dftl:qc:maxStretch",
    "penetration": "dftl:qc:maxPenetration",
    "speed": "dftl:qc:maxSpeed",
    "energy": "dftl:qc:energy",
    "nan": "dftl:qc:nanCount",
}
METRICS = tuple(ATTRIBUTES)
#: the prim under which the QC attributes live
QC_ROOT = "/dftl_qc"


class QCError(UserError):
    """A ``--check`` gate is broken (``simulate`` exits with status 3)."""

    exit_status = 3


def parse_gates(text: str | None, name: str = "--check") -> dict[str, float]:
    """``'stretch<1e-3, penetration<0.05'`` -> ``{"stretch": 0.001, "penetration": 0.05}``; a bad
    gate is a UserError naming the option as ``name`` (``--check`` on the command line, ``check``
    for the API and job files). None is no gates; an empty text is refused (``--check ''`` was
    "check must be a string")."""
    if text is None:
        return {}
    example = f"METRIC<LIMIT gates such as 'stretch<1e-3,penetration<0.05' (metrics: {', '.join(METRICS)})"
    if not isinstance(text, str):
        raise UserError(f"{name} {text!r}: expected a string of {example}")
    if not text.strip():
        raise UserError(f"{name} {text!r}: no gates: give {example}")
    gates = {}
    for part in text.split(","):
        m = re.fullmatch(r"\s*([a-z]+)\s*<\s*(\S+)\s*", part)
        if not m or m.group(1) not in METRICS:
            raise UserError(f"{name} {text!r}: each gate is METRIC<LIMIT with METRIC one of {', '.join(METRICS)}")
        try:
            limit = float(m.group(2))
        except ValueError:
            raise UserError(f"{name} {text!r}: {m.group(2)!r} is not a number") from None
        if not math.isfinite(limit):
            raise UserError(f"{name} {text!r}: the limit of {m.group(1)} must be finite")
        gates[m.group(1)] = limit
    return gates


def check(gates: dict, frame: int, qc: dict) -> None:
    """Raise :class:`QCError` for the first prim of ``qc`` (prim path -> metrics) whose metric is
    not below its gate (a NaN metric breaks every gate on it)."""
    for prim, metrics in qc.items():
        for name, limit in gates.items():
            value = metrics.get(name)
            if value is None:
                continue
            if not value < limit:
                raise QCError(f"QC gate {name}<{limit:g} broken at frame {frame} by {prim}: {name} = {value:.6g}")


def qc_prim_name(prim_path: str) -> str:
    """``/World/Hair`` -> ``World_Hair`` (a valid prim name; ``dftl:qc:prim`` keeps the path)."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", prim_path.strip("/")) or "root"
    return name if not name[0].isdigit() else "_" + name


class ColliderDepth:
    """The penetration QC of one model (a part) against its colliders, per frame: a step struct of
    the colliders' fields at ``control``'s current pose (the same device arrays the step moves),
    with the previous pose set to the current one (the measurement moves nothing: no friction)
    and meshes queried to any depth; :meth:`launch` is one kernel launch
    (:func:`~dftl_warp.kernels.output.penetration.prim_penetration_kernel`).
    ``default_radius``: the unit of depth (stage units) where a particle has no hair width."""

    def __init__(self, model, control, default_radius: float):
        import warp as wp

        from ..kernels.features.collide import collider_flags
        from ..kernels.features.step import feature_struct
        from ..kernels.output.penetration import prim_penetration_kernel

        self.model = model
        flags = frozenset(model.feature_flags) & frozenset(collider_flags())
        Features = feature_struct(model.scalar, flags)
        cc = control.features.colliders
        st = Features()
        cc.fill_struct(st, still=True)
        meshes = cc.kind_data.get("meshes")
        self._band = None
        if meshes is not None:
            self._band = wp.full(meshes.depth_band.shape[0], ANY_DEPTH, dtype=model.scalar, device=model.device)
            st.collider_depth_band = self._band
        self.struct = st
        self.kernel = prim_penetration_kernel(model.scalar, Features, flags)
        self.default_radius = float(default_radius)

    @staticmethod
    def present(model, control) -> bool:
        """Whether ``model`` has colliders (and ``control`` their poses)."""
        fd = getattr(model, "feature_data", None)
        fc = getattr(control, "features", None)
        return (fd is not None and fd.collider_data is not None and fc is not None
                and getattr(fc, "colliders", None) is not None)

    def launch(self, state, strand_member, penetration) -> None:
        """Atomic max of each strand's deepest penetration (hair radii) into ``penetration[prim]``
        (float64, zeroed by the caller) for ``state``'s positions."""
        import warp as wp

        m = self.model
        wp.launch(self.kernel, dim=m.num_strands, device=m.device,
                  inputs=[m.strand_base, m.strand_stride, m.strand_count, strand_member, self.struct,
                          self.default_radius, state.positions],
                  outputs=[penetration])


def prim_penetration(model, state, control, strand_member, num_prims: int, default_radius: float) -> np.ndarray:
    """Per prim (``strand_member``: prim index of each device strand, int32 numpy or device
    array), the deepest penetration of ``state`` into ``control``'s colliders in hair radii
    (module docstring); zeros without colliders."""
    import warp as wp

    if not ColliderDepth.present(model, control) or model.num_strands == 0:
        return np.zeros(num_prims)
    member = strand_member if isinstance(strand_member, wp.array) else wp.array(
        np.asarray(strand_member, dtype=np.int32), dtype=wp.int32, device=model.device)
    out = wp.zeros(num_prims, dtype=wp.float64, device=model.device)
    ColliderDepth(model, control, default_radius).launch(state, member, out)
    return out.numpy()


class FrameQC:
    """The QC of a :class:`~dftl_warp.simulation.simulate.Simulation`'s current frame.

    Per group and part: the device strand -> member prim map (on the device, made once; a
    particle-major layout orders a part's strands by their roots, not by prim) and 5 output
    slots per member prim. :meth:`compute` launches one kernel per part, a second where the part
    has colliders (penetration), and reads back the slots. ``notes``: one line per prim whose
    penetration is measured from the surface in default hair radii (no widths); also appended to
    the simulation's ``start_notes`` (printed and kept with its warnings).
    """

    def __init__(self, sim):
        import warp as wp

        from ..features.scene import widths_per_point
        from ..solvers.elastic_material import default_radius

        self.sim = sim
        self.gravity = wp.vec3d(*[float(x) for x in sim.scene.gravity])
        unit = default_radius(sim.scene.stage.meters_per_unit)
        self.notes = []
        self.parts = []  # (group, member index offset, model, state index, arrays)
        for g in sim.groups:
            strands = np.concatenate([np.full(c.num_strands, k, dtype=np.int32) for k, c in enumerate(g.curves)])
            models = g.model.parts if hasattr(g.model, "parts") else [g.model]
            controls = g.control.parts if hasattr(g.control, "parts") else [g.control]
            ranges = g.model.strand_ranges if hasattr(g.model, "parts") else [(0, len(strands))]
            for j, (model, control, (s0, s1)) in enumerate(zip(models, controls, ranges)):
                d = model.device
                n = len(g.members)
                depth = ColliderDepth(model, control, unit) if ColliderDepth.present(model, control) else None
                order = np.asarray(model.layout.strand_order)   # device strand -> the part's input strand
                self.parts.append({
                    "group": g, "part": j, "model": model, "strands": s1 - s0, "depth": depth, "order": order,
                    "member": wp.array(strands[s0:s1][order], dtype=wp.int32, device=d),
                    "stretch": wp.zeros(n, dtype=wp.float64, device=d),
                    "speed": wp.zeros(n, dtype=wp.float64, device=d),
                    "energy": wp.zeros(max(s1 - s0, 1), dtype=wp.float64, device=d),
                    "nans": wp.zeros(n, dtype=wp.int32, device=d),
                    "penetration": wp.zeros(n, dtype=wp.float64, device=d),
                })
            if ColliderDepth.present(models[0], controls[0]):
                for c in g.curves:
                    w = widths_per_point(c)
                    if w is None or not np.all(w > 0):
                        self.notes.append(
                            f"{c.path}: {'no' if w is None else 'zero'} hair widths: its QC penetration is the depth "
                            f"below the collider surfaces (their contact distance 0) in units of the default hair "
                            f"radius, {unit:.3g} stage units (40 um)")
        if hasattr(sim, "start_notes"):   # once (a resumed batch job's came with its checkpoint)
            sim.start_notes.extend(n for n in self.notes if n not in sim.start_notes)

    def compute(self) -> dict[str, dict]:
        """prim path -> {stretch, penetration, speed, energy, nan} at the simulation's current frame."""
        import warp as wp

        from ..kernels.output.qc import prim_qc_kernel

        for p in self.parts:
            g, model = p["group"], p["model"]
            state = g.state.parts[p["part"]] if hasattr(g.state, "parts") else g.state
            for name in ("stretch", "speed", "energy", "nans", "penetration"):
                p[name].zero_()
            if p["strands"]:
                wp.launch(prim_qc_kernel(model.scalar), dim=p["strands"], device=model.device,
                          inputs=[model.strand_base, model.strand_stride, model.strand_count, p["member"],
                                  model.rest_lengths, self.gravity, wp.vec3d(*[float(x) for x in model.origin]),
                                  state.positions, state.velocities],
                          outputs=[p["stretch"], p["speed"], p["energy"], p["nans"]])
                if p["depth"] is not None:
                    p["depth"].launch(state, p["member"], p["penetration"])
        out: dict = {}
        energies: dict = {}  # group -> per-strand energies in strand order
        for p in self.parts:
            per_strand = np.empty(p["strands"])
            per_strand[p["order"]] = p["energy"].numpy()[:p["strands"]]   # device order -> input order
            energies.setdefault(id(p["group"]), []).append(per_strand)
        for p in self.parts:
            g = p["group"]
            values = {k: p[k].numpy() for k in ("stretch", "speed", "nans", "penetration")}
            if p["part"] == 0:
                strand_energy = np.concatenate(energies[id(g)])
                counts = [c.num_strands for c in g.curves]
                values["energy"] = [float(np.sum(x)) for x in np.split(strand_energy, np.cumsum(counts)[:-1])]
            else:
                values["energy"] = [0.0] * len(g.members)
            for k, i in enumerate(g.members):
                path = self.sim.scene.curves[i].path
                q = out.setdefault(path, {"stretch": 0.0, "penetration": 0.0, "speed": 0.0, "energy": 0.0, "nan": 0})
                q["stretch"] = max(q["stretch"], float(values["stretch"][k]))
                q["penetration"] = max(q["penetration"], float(values["penetration"][k]))
                q["speed"] = max(q["speed"], float(values["speed"][k]))
                q["energy"] += float(values["energy"][k])
                q["nan"] += int(values["nans"][k])
        order = [c.path for c in self.sim.scene.curves]
        return {path: out[path] for path in order if path in out}
