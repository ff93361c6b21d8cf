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
    #: about the input and the clean start (printed by the command after the run; those also in
    #: ``start_notes`` were printed before it when progress was shown)
    warnings: list[str] = field(default_factory=list)
    #: raised while simulating, e.g. energy growth (printed as they happen when progress is shown)
    run_warnings: list[str] = field(default_factory=list)
    #: ``--tolerance``: what was chosen (simulation.tolerance.Tolerance.lines)
    tolerance: list[str] = field(default_factory=list)
    #: the clean start's and the preroll's lines (hair moved out of colliders, settling)
    start_notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return asdict(self)
