"""Reading what changes over time up front, so that the Scene holds no open stage.

Transforms and animated mesh points are read at the time codes the simulation asks for and kept
as plain :class:`~dftl_warp.usd.scene.Samples`:

- a local-to-world transform at every integer frame from its first to its last authored time
  sample (of any xformOp of the prim or its ancestors), clipped to the run's frames when they are
  known, plus the authored time samples themselves: the simulation's frames get exactly USD's
  value; between samples the matrices interpolate linearly; outside them the transform holds;
- mesh points at their authored time samples: USD interpolates points linearly between samples,
  and so do the Samples.

Every sample is checked when read (finite, not singular): a bad transform at any frame of the run
is refused before the run starts.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import UserError
from ..checks import check_lengths
from .scene import Constant, Samples

#: most integer frames read densely per animated transform (beyond: the authored time samples and
#: the run's frames only)
MAX_DENSE_FRAMES = 20000


def _code(time):
    from pxr import Usd

    return Usd.TimeCode.Default() if time is None else Usd.TimeCode(float(time))


def _held(stage) -> bool:
    from pxr import Usd

    return stage.GetInterpolationType() == Usd.InterpolationTypeHeld


def sample_times(knots, frames=None, read_time=None) -> np.ndarray:
    """Time codes to read a transform at: ``knots`` (its authored time samples), every integer
    frame between the first and last knot (within ``frames`` +- 1 when given), ``frames`` when the
    knots are too far apart to read densely, and ``read_time``."""
    knots = np.unique(np.asarray(list(knots), dtype=np.float64))
    extra = [] if read_time is None else [float(read_time)]
    if knots.size == 0:
        return np.unique(np.array(extra or [0.0]))
    lo, hi = float(knots[0]), float(knots[-1])
    if frames is not None:
        first, last = frames
        if first is not None:
            lo = max(lo, math.floor(first) - 1.0)
        if last is not None:
            hi = min(hi, math.ceil(last) + 1.0)
    dense = np.arange(math.ceil(lo), math.floor(hi) + 1, dtype=np.float64) if hi >= lo else np.zeros(0)
    if dense.size > MAX_DENSE_FRAMES:
        dense = np.zeros(0)
        if frames is not None and frames[0] is not None and frames[1] is not None \
                and frames[1] - frames[0] + 3 <= MAX_DENSE_FRAMES:
            dense = np.arange(frames[0] - 1, frames[1] + 2, dtype=np.float64)
    return np.unique(np.concatenate([knots, dense, np.array(extra)]))


class TransformReader:
    """Local-to-world transforms of a stage's prims, read up front (:meth:`sampler`).

    One ``UsdGeom.XformCache`` per time code shares the ancestors' work between prims.
    """

    def __init__(self, stage, file: str, frames=None):
        self.stage = stage
        self.file = file
        self.frames = frames
        self.held = _held(stage)
        self._caches: dict = {}

    def _matrix(self, prim, time, where: str) -> np.ndarray:
        from pxr import Tf, UsdGeom

        from .stage import tf_message

        cache = self._caches.get(time)
        if cache is None:
            cache = self._caches[time] = UsdGeom.XformCache(_code(time))
        try:
            m = np.array(cache.GetLocalToWorldTransform(prim), dtype=np.float64)
        except Tf.ErrorException as exc:   # an xformOp of the wrong type (string xformOp:translate)
            raise UserError(f"{where}: local-to-world transform at time {time}: "
                            f"{tf_message(exc).removesuffix(' Returning identity matrix.')}") from None
        if not np.all(np.isfinite(m)):
            raise UserError(f"{where}: local-to-world transform at time {time} is not finite")
        if abs(np.linalg.det(m[:3, :3])) < 1e-300:
            raise UserError(f"{where}: local-to-world transform at time {time} is singular (zero scale)")
        return m

    def sampler(self, prim, read_time):
        """``(sampler, animated)`` for ``prim``'s local-to-world transform: a
        :class:`~dftl_warp.usd.scene.Constant` (static) or :class:`~dftl_warp.usd.scene.Samples`."""
        from pxr import UsdGeom

        where = f"{self.file}: {prim.GetPath()}"
        animated = False
        knots: set = set()
        p = prim
        while p and not p.IsPseudoRoot():
            xf = UsdGeom.Xformable(p)
            if xf:
                if xf.TransformMightBeTimeVarying():
                    animated = True
                knots.update(xf.GetTimeSamples())
                if xf.GetResetXformStack():
                    break
            p = p.GetParent()
        if not animated:
            return Constant(self._matrix(prim, read_time, where)), False
        times = sample_times(knots, self.frames, read_time)
        matrices = np.stack([self._matrix(prim, t, where) for t in times])
        return Samples(times, matrices, held=self.held), True


def scale_growth(sampler, read_time) -> float:
    """How far the scale of a transform ``sampler`` (:meth:`TransformReader.sampler`) strays from
    its scale at ``read_time``: the largest ratio (>= 1) of the length of a local axis in the world
    at a sample to its length at ``read_time``, either way; 1 for a static transform."""
    values = getattr(sampler, "values", None)
    if values is None:
        return 1.0
    axes = np.linalg.norm(values[:, :3, :3], axis=2)
    ratio = axes / np.linalg.norm(sampler(read_time)[:3, :3], axis=1)
    return float(np.maximum(ratio, 1.0 / ratio).max())


def points_sampler(attr, count: int, where: str, read_time, static_points: np.ndarray):
    """``(sampler, animated)`` for a mesh's local points: every authored time sample when they
    change over time (each checked: ``count`` finite points, none too large for float32:
    :func:`~dftl_warp.checks.check_lengths`), else the points read at ``read_time``."""
    if not attr.ValueMightBeTimeVarying():
        return Constant(static_points), False
    times = list(attr.GetTimeSamples())
    rows = []
    for t in times:
        p = np.array(attr.Get(_code(t)) or [], dtype=np.float64).reshape(-1, 3)
        if p.shape[0] != count or not np.isfinite(p).all():
            raise UserError(f"{where}: points at time {t:g} are not {count} finite points")
        check_lengths(p, "points", where, world=f" at time {t:g}")
        rows.append(p)
    if not rows:
        return Constant(static_points), False
    return Samples(times, np.stack(rows), held=_held(attr.GetPrim().GetStage())), True
