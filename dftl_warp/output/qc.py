"""Per-frame QC stored in the cache, and ``--check`` gates (docs/caches.md).

Every written frame gets, per simulated prim, computed on the simulation device by one small
kernel per part (:mod:`dftl_warp.kernels.output.qc`):

| metric | attribute | meaning |
|---|---|---|
| ``stretch`` | ``dftl:qc:maxStretch`` | max over segments of abs(length / rest length - 1) |
| ``speed`` | ``dftl:qc:maxSpeed`` | max particle speed, world space, stage units / s |
| ``energy`` | ``dftl:qc:energy`` | sum over free particles of 0.5 v^2 - g . x (per unit mass, stage units^2 / s^2) |
| ``nan`` | ``dftl:qc:nanCount`` | particles with a non-finite position or velocity |
| ``penetration`` | ``dftl:qc:maxPenetration`` | max collider penetration / hair radius: not computed yet (omitted) |

Maxima and counts are reduced with atomics (exact in any order); energy comes back per strand and
is summed on the host in strand order, so the QC is bitwise the same split over devices or not.

A writer stores them with :meth:`~dftl_warp.output.base.FrameWriter.write_qc` (USD: time samples
on ``/dftl_qc/<prim path with / as _>``, whose ``dftl:qc:prim`` names the prim).

``--check 'stretch<1e-3,speed<50'``: :func:`parse_gates`; :func:`check` raises :class:`QCError`
(exit status 3 from ``simulate``, a failed job in ``batch``) naming the first frame and prim that
breaks a gate. A gate on a metric a prim does not have (penetration) does not apply to it.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import UserError

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


def parse_gates(text: str | None) -> dict[str, float]:
    """``'stretch<1e-3, penetration<0.05'`` -> ``{"stretch": 0.001, "penetration": 0.05}``."""
    if not text:
        return {}
    gates = {}
    for part in text.split(","):
        m = re.fullmatch(r"\s*([a-z]+)\s*<\s*(\S+)\s*", part)
        if not m or m.group(1) not in METRICS:
            raise UserError(f"--check {text!r}: each gate is METRIC<LIMIT with METRIC one of {', '.join(METRICS)}")
        try:
            limit = float(m.group(2))
        except ValueError:
            raise UserError(f"--check {text!r}: {m.group(2)!r} is not a number") from None
        if not math.isfinite(limit):
            raise UserError(f"--check {text!r}: the limit of {m.group(1)} must be finite")
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


class FrameQC:
    """The QC of a :class:`~dftl_warp.simulation.simulate.Simulation`'s current frame.

    Per group and part: the strand -> member prim map (on the device, made once) and 4 output
    slots per member prim. :meth:`compute` launches one kernel per part and reads back the slots.
    """

    def __init__(self, sim):
        import warp as wp

        self.sim = sim
        self.gravity = wp.vec3d(*[float(x) for x in sim.scene.gravity])
        self.parts = []  # (group, member index offset, model, state index, arrays)
        for g in sim.groups:
            strands = np.concatenate([np.full(c.num_strands, k, dtype=np.int32) for k, c in enumerate(g.curves)])
            models = g.model.parts if hasattr(g.model, "parts") else [g.model]
            ranges = g.model.strand_ranges if hasattr(g.model, "parts") else [(0, len(strands))]
            for j, (model, (s0, s1)) in enumerate(zip(models, ranges)):
                d = model.device
                n = len(g.members)
                self.parts.append({
                    "group": g, "part": j, "model": model, "strands": s1 - s0,
                    "member": wp.array(strands[s0:s1], dtype=wp.int32, device=d),
                    "stretch": wp.zeros(n, dtype=wp.float64, device=d),
                    "speed": wp.zeros(n, dtype=wp.float64, device=d),
                    "energy": wp.zeros(max(s1 - s0, 1), dtype=wp.float64, device=d),
                    "nans": wp.zeros(n, dtype=wp.int32, device=d),
                })

    def compute(self) -> dict[str, dict]:
        """prim path -> {stretch, speed, energy, nan} at the simulation's current frame."""
        import warp as wp

        from ..kernels.output.qc import prim_qc_kernel

        for p in self.parts:
            g, model = p["group"], p["model"]
            state = g.state.parts[p["part"]] if hasattr(g.state, "parts") else g.state
            for name in ("stretch", "speed", "energy", "nans"):
                p[name].zero_()
            if p["strands"]:
                wp.launch(prim_qc_kernel(model.scalar), dim=p["strands"], device=model.device,
                          inputs=[model.strand_base, model.strand_stride, model.strand_count, p["member"],
                                  model.rest_lengths, self.gravity, wp.vec3d(*[float(x) for x in model.origin]),
                                  state.positions, state.velocities],
                          outputs=[p["stretch"], p["speed"], p["energy"], p["nans"]])
        out: dict = {}
        energies: dict = {}  # group -> per-strand energies in strand order
        for p in self.parts:
            energies.setdefault(id(p["group"]), []).append(p["energy"].numpy()[:p["strands"]])
        for p in self.parts:
            g = p["group"]
            values = {k: p[k].numpy() for k in ("stretch", "speed", "nans")}
            if p["part"] == 0:
                strand_energy = np.concatenate(energies[id(g)])
                counts = [c.num_strands for c in g.curves]
                values["energy"] = [float(np.sum(x)) for x in np.split(strand_energy, np.cumsum(counts)[:-1])]
            else:
                values["energy"] = [0.0] * len(g.members)
            for k, i in enumerate(g.members):
                path = self.sim.scene.curves[i].path
                q = out.setdefault(path, {"stretch": 0.0, "speed": 0.0, "energy": 0.0, "nan": 0})
                q["stretch"] = max(q["stretch"], float(values["stretch"][k]))
                q["speed"] = max(q["speed"], float(values["speed"][k]))
                q["energy"] += float(values["energy"][k])
                q["nan"] += int(values["nans"][k])
        order = [c.path for c in self.sim.scene.curves]
        return {path: out[path] for path in order if path in out}
