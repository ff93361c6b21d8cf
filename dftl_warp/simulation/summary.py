"""What a run of :func:`~dftl_warp.simulation.simulate.simulate_usd` did (:class:`Summary`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field


@dataclass
class Summary:
    """What :func:`simulate_usd` did. Times in seconds."""

    output: str
    prims: int
    strands: int
    particles: int
    frames: int
    first_frame: int
    last_frame: int
    colliders: int
    seconds_loading: float
    seconds_simulating: float
    seconds_writing: float
    groups: list[dict] = field(default_factory=list)
    #: everything known before the first frame was simulated: the input's warnings (unknown ``dftl:``
    #: attributes, frames outside the stage's time range or left out by ``frame_step``, approximated
    #: colliders, options no prim uses, ...), then ``start_notes``. Printed before the frames run when
    #: progress is shown (``simulate -q``: by the command after the run); a settled preroll's line is
    #: a note, the others warnings (:func:`~dftl_warp.output.progress.is_plain_note`)
    warnings: list[str] = field(default_factory=list)
    #: raised while simulating, e.g. energy growth (printed as they happen when progress is shown)
    run_warnings: list[str] = field(default_factory=list)
    #: ``--tolerance``: what was chosen (simulation.tolerance.Tolerance.lines)
    tolerance: list[str] = field(default_factory=list)
    #: the lines of ``warnings`` that the simulation's set-up gave (``Simulation.start_notes``, which a
    #: batch checkpoint keeps for the run it resumes): the clean start's and the preroll's (hair moved
    #: out of colliders, settling), deforming collider meshes changing once a frame, a quality preset
    #: that leaves prims with widths on the elastic solver, and the QC's notes (penetration measured in
    #: default hair radii for prims without widths)
    start_notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return asdict(self)
