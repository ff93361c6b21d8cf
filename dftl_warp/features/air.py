"""Air: drag toward the air's velocity (:class:`Drag`) and wind (:class:`Wind`).

Model data: the drag rate per device strand (1/s). Control (:class:`WindControl`): the wind
velocity at frame start and end (m/s) and, for the curl noise, the frame's start and end times
(s). USD: ``dftl:drag`` (scene or curves prim), ``dftl:wind`` (scene, time-sampled for gusts) and
the ``dftl:windNoise*`` attributes. The sweep (``kernels/solvers/featured.py``) relaxes each
velocity toward the air's, ``v = w + (v - w) exp(-rate dt)``, before the prediction.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ..core.precision import numpy_type
from .base import authored, authored_per_strand, nonnegative, per_strand, vector

#: name -> (type, where: "scene", "curves" or "both", description)
ATTRIBUTES = {
    "dftl:drag": (float, "both", "air drag rate (1/s): velocities relax toward the air's velocity; 0 or unset: no drag"),
    "dftl:wind": ("float3", "scene", "wind velocity (stage units/s), time-sampled for gusts; needs dftl:drag > 0"),
    "dftl:windNoise": (float, "scene", "curl-noise amplitude added to the wind (stage units/s)"),
    "dftl:windNoiseScale": (float, "scene", "feature size of the noise (stage units)"),
    "dftl:windNoiseFrequency": (float, "scene", "how fast the noise changes (1/s)"),
    "dftl:windSeed": (int, "scene", "noise field selector"),
}


@dataclass(frozen=True, eq=False)
class Drag:
    """Air drag: velocities relax toward the air's at ``rate`` (1/s), ``v = w + (v - w) exp(-rate dt)``.

    ``rate`` is a number or one per input strand (per curve)."""

    rate: object = 1.0

    def __post_init__(self):
        r = np.asarray(self.rate)
        if r.dtype.kind not in "iuf":   # "1" and True were taken through float()
            raise ValueError(f"drag rate must be a number or one per strand (1/s), got {self.rate!r}")
        r = r.astype(np.float64)
        if not np.isfinite(r).all() or np.any(r < 0):
            raise ValueError("drag rate must be finite and >= 0 (1/s)")
        object.__setattr__(self, "rate", r)

    flags = frozenset({"drag"})


@dataclass(frozen=True, eq=False)
class Wind:
    """Air velocity (m/s) for :class:`Drag`: ``velocity`` (3,) constant, or keyframes (K, 4) of
    ``(time s, vx, vy, vz)`` interpolated linearly (held before the first and after the last).

    ``noise_amplitude`` (m/s) adds divergence-free curl noise of feature size ``noise_scale`` (m)
    changing at ``noise_frequency`` (1/s), field chosen by ``seed``."""

    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    noise_amplitude: float = 0.0
    noise_scale: float = 0.1
    noise_frequency: float = 1.0
    seed: int = 0

    def __post_init__(self):
        v = np.asarray(self.velocity, dtype=np.float64)
        if v.shape == (3,):
            v = np.concatenate([[0.0], v])[None]
        if v.ndim != 2 or v.shape[1] != 4 or len(v) == 0 or not np.isfinite(v).all():
            raise ValueError("wind velocity must be (3,) or keyframes (K, 4) of (time, vx, vy, vz)")
        if np.any(np.diff(v[:, 0]) < 0):
            raise ValueError("wind keyframe times must increase")
        object.__setattr__(self, "velocity", v)
        nonnegative(self.noise_amplitude, "wind noise_amplitude")
        for name, unit in (("noise_scale", "m"), ("noise_frequency", "1/s")):
            value = getattr(self, name)
            try:
                v = float(value)
            except (TypeError, ValueError):
                v = float("nan")
            if not (np.isfinite(v) and (v > 0 if name == "noise_scale" else v >= 0)):
                raise ValueError(f"wind {name} must be a finite number {'>' if name == 'noise_scale' else '>='} 0 "
                                 f"({unit}), got {value!r}")

    def at(self, time: float) -> np.ndarray:
        """Wind velocity (3,) at ``time`` (s)."""
        k = self.velocity
        return np.array([np.interp(time, k[:, 0], k[:, c]) for c in (1, 2, 3)])

    @property
    def flags(self):
        return frozenset({"wind", "wind_noise"} if self.noise_amplitude > 0 else {"wind"})


def build_drag(drag: Drag, num_strands: int, strand_order, scalar, ftype, device) -> wp.array:
    """Drag rate (1/s) per device strand."""
    rate = per_strand(drag.rate, num_strands, "drag rate")[strand_order].astype(ftype)
    return wp.array(np.ascontiguousarray(rate), dtype=scalar, device=device)


class WindControl:
    """The frame's wind: ``velocity`` (2,) at frame start and end (m/s, Warp array) and ``time``
    (2,) at frame start and end (s), both interpolated across the substeps."""

    def __init__(self, wind: Wind, model):
        self.wind = wind
        self._precision = model.precision
        v = wind.at(0.0)
        self.velocity = wp.array(np.array([v, v], dtype=numpy_type(model.precision)), dtype=model.vec3,
                                 device=model.device)
        self.time = wp.zeros(2, dtype=model.scalar, device=model.device)

    def set_frame_time(self, start: float, end: float) -> None:
        """The frame spans ``start`` -> ``end`` seconds: wind velocity from its keyframes, noise time."""
        f = numpy_type(self._precision)
        self.velocity.assign(np.array([self.wind.at(start), self.wind.at(end)], dtype=f))
        self.time.assign(np.array([start, end], dtype=f))

    def set_wind(self, start, end=None) -> None:
        """Wind velocity (3,) m/s at frame start and end (overrides the keyframes for this frame)."""
        f = numpy_type(self._precision)
        start = vector(start, 3, "set_wind: start (wind velocity, m/s)")
        end = start if end is None else vector(end, 3, "set_wind: end (wind velocity, m/s)")
        self.velocity.assign(np.array([start, end], dtype=f))


def fill_struct(st, flags, drag_rate, wind: WindControl | None) -> None:
    """The air's fields of the step struct."""
    if "drag" in flags:
        st.drag = drag_rate
    if "wind" in flags:
        st.wind_velocity = wind.velocity
    if "wind_noise" in flags:
        w = wind.wind
        st.wind_time = wind.time
        st.noise_amplitude = float(w.noise_amplitude)
        st.noise_inv_scale = 1.0 / float(w.noise_scale)
        st.noise_frequency = float(w.noise_frequency)
        st.noise_seed = int(w.seed)


def from_attributes(scene: dict, curves: list, counts: list, where: str) -> list:
    """Drag (and Wind) from authored ``dftl:drag`` / ``dftl:wind*`` values (see
    :func:`dftl_warp.features.scene.features_from_attributes`)."""

    def nonneg(v, msg):
        if v < 0:
            raise ValueError(f"{msg}: must be >= 0")

    drag = authored_per_strand(scene, curves, counts, "dftl:drag", where, nonneg)
    wind = scene.get("dftl:wind")
    if not (np.any(drag > 0) or wind is not None):
        return []
    if wind is not None and not np.any(drag > 0):
        raise ValueError(f"{where}: dftl:wind acts through air drag: author dftl:drag > 0")
    feats = [Drag(drag)]
    if wind is not None:
        try:
            feats.append(Wind(
                velocity=np.asarray(wind, dtype=np.float64),
                noise_amplitude=authored(scene, "dftl:windNoise", where, float, 0.0),
                noise_scale=authored(scene, "dftl:windNoiseScale", where, float, 0.1),
                noise_frequency=authored(scene, "dftl:windNoiseFrequency", where, float, 1.0),
                seed=authored(scene, "dftl:windSeed", where, int, 0)))
        except ValueError as exc:
            raise ValueError(f"{where}: dftl:wind: {exc}") from None
    return feats
