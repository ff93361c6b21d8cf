"""The one module that writes USD: simulated frames -> a layer that sublayers the input.

The output layer holds

- the input's stage metadata (defaultPrim, upAxis, metersPerUnit, timeCodesPerSecond,
  framesPerSecond, start/end time codes; effective values where the input leaves them unauthored),
- a sublayer reference to the input (relative to the output's folder where possible),
- an ``over`` spec per simulated BasisCurves prim with time-sampled ``points`` (stage units),
  ``velocities`` (stage units / s) and ``extent`` at every frame, all in the prim's local space.

Frames stream in through :meth:`UsdWriter.write_frame`, authored with the Sdf API inside change
blocks into a crate (``.usdc``) *partial* file next to the output. Whenever ``flush_bytes`` of new
samples have accumulated, the layer is saved: crate appends the new samples to the file and reads
them back lazily from disk, so memory stays flat however many frames are written.
:meth:`UsdWriter.commit` saves the last frames and renames the partial file onto the output (for
``.usda`` outputs it exports text first); :meth:`UsdWriter.abort` deletes it. An interrupted run
therefore never leaves a half-written output. :meth:`UsdWriter.reopen` continues a partial file
(the batch / resume feature).

The partial file of a resumable writer (``keep_partial=True``, batch) has the fixed name
:func:`partial_path` that :meth:`UsdWriter.reopen` finds; any other writer streams into a unique
name (``.NAME.dftl-partial.XXXXXXXX.usdc``), so that two runs writing one output never share a
file. Both kinds run under the output's lock (:mod:`dftl_warp.output.lock`), taken by
``simulate`` and ``batch``. The output's folder is created when missing.

The layer's start and end time codes are the simulated frames, whatever the input's range.
Records (:meth:`UsdWriter.set_record`: batch's settings hash) live in the layer's
``customLayerData``. :class:`UsdWriter` is the :class:`~dftl_warp.output.base.FrameWriter` of
``.usdc``, ``.usda`` and ``.usd`` outputs.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..durable import replace_file
from ..errors import UserError
from .base import FrameWriter, ensure_folder  # noqa: F401  (ensure_folder: re-exported)
from .paths import check_writable
from .qc import ATTRIBUTES, QC_ROOT, qc_prim_name
from .vtarrays import vec3f_array

OUTPUT_EXTENSIONS = (".usdc", ".usda", ".usd")
#: save (and so release) the in-memory samples once this many new bytes have accumulated
DEFAULT_FLUSH_BYTES = 4 << 20


def partial_path(output) -> Path:
    """The crate file frames are streamed into before it becomes ``output``."""
    output = Path(output)
    return output.with_name(f".{output.name}.dftl-partial.usdc")


def unique_partial_path(output) -> Path:
    """A new, empty file next to ``output`` that no other run uses (``.NAME.dftl-partial.XXXXXXXX.usdc``)."""
    import tempfile

    output = Path(output)
    try:
        fd, name = tempfile.mkstemp(prefix=f".{output.name}.dftl-partial.", suffix=".usdc", dir=output.parent)
    except OSError as exc:
        raise UserError(f"{output}: cannot write: {exc.strerror or exc}") from None
    os.close(fd)
    return Path(name)


def check_output_path(output, input_path=None) -> Path:
    """Refuse outputs that cannot be written, before any work is done. A missing folder is
    fine when it can be created (:func:`ensure_folder` creates it)."""
    output = Path(os.fspath(output))
    if output.suffix.lower() not in OUTPUT_EXTENSIONS:
        raise UserError(f"{output}: output must end in {', '.join(OUTPUT_EXTENSIONS)} (.usdc is the default)")
    check_writable(output)
    if input_path is not None and output.exists() and Path(input_path).exists():
        if os.path.samefile(output, input_path):
            raise UserError(f"{output}: the output would overwrite the input")
    return output


def sublayer_path(input_path: str, output: Path) -> str:
    """Asset path of ``input_path`` as seen from ``output``: relative ("./x.usda", "../x.usda")
    where possible, absolute otherwise."""
    if "://" in input_path or input_path.startswith("anon:"):
        return input_path
    try:
        rel = os.path.relpath(os.path.abspath(input_path), os.path.abspath(output.parent or "."))
    except ValueError:  # other drive
        return os.path.abspath(input_path).replace(os.sep, "/")
    rel = rel.replace(os.sep, "/")
    return rel if rel.startswith("../") else "./" + rel


def _tf_error(exc) -> str:
    from ..usd.stage import tf_message as _tf_message

    return _tf_message(exc)


@dataclass
class _Target:
    """Attribute spec paths of one simulated prim."""

    prim: str
    points: object
    velocities: object
    extent: object
    #: widths (local stage units) used to pad the extent, or None
    widths: object


class UsdWriter(FrameWriter):
    """Streams frames of a simulation into a layer that sublayers the input.

    Create with :meth:`create` (new output) or :meth:`reopen` (continue a partial file); write
    frames in increasing time code order with :meth:`write_frame`; finish with :meth:`commit` or
    :meth:`abort`. As a context manager it aborts on any exception.
    """

    extensions = OUTPUT_EXTENSIONS
    resumable = True
    create_options = ("velocities", "flush_bytes")

    def __init__(self, layer, output: Path, targets: list[_Target], *, flush_bytes: int, keep_partial: bool = False):
        self.layer = layer
        self.output = output
        self.partial = Path(layer.realPath)
        self.targets = targets
        self.flush_bytes = int(flush_bytes)
        #: leave the partial file on abort (for resumable batch runs)
        self.keep_partial = keep_partial
        self._unsaved = 0
        #: QC prim name -> {metric: attribute spec path} (made on the first write_qc)
        self._qc: dict = {}
        self.frames_written = 0
        self.seconds_saving = 0.0

    # -- construction ------------------------------------------------------------------------

    @classmethod
    def create(cls, output, scene, *, frames: tuple[int, int] | None = None,
               flush_bytes: int = DEFAULT_FLUSH_BYTES, keep_partial: bool = False,
               velocities: bool = True) -> UsdWriter:
        """A new partial file for ``output``: metadata, sublayer and ``over`` specs, saved once
        (so that an unwritable location fails now, not after the simulation).

        ``frames`` (first, last) is authored as the layer's start/end time codes (else the
        input's). ``velocities=False`` authors no velocities (``--no-velocities``). A
        ``keep_partial`` (resumable) writer streams into :func:`partial_path`, any
        other into a :func:`unique_partial_path`. The output's folder is created if missing.
        """
        from pxr import Sdf, Tf

        output = check_output_path(output, scene.source)
        ensure_folder(output)
        if keep_partial:
            partial = partial_path(output)
            _remove(partial)
        else:
            partial = unique_partial_path(output)
        try:
            layer = Sdf.Layer.CreateNew(str(partial))
        except Tf.ErrorException as exc:
            _remove(partial)
            raise UserError(f"{output}: cannot write: {_tf_error(exc)}") from None
        if layer is None:
            _remove(partial)
            raise UserError(f"{output}: cannot write {partial}")
        try:
            targets = _author_structure(layer, scene, output, frames, velocities=velocities)
            layer.Save()
        except Tf.ErrorException as exc:
            _remove(partial)
            raise UserError(f"{output}: cannot write: {_tf_error(exc)}") from None
        except BaseException:
            _remove(partial)
            raise
        return cls(layer, output, targets, flush_bytes=flush_bytes, keep_partial=keep_partial)

    @classmethod
    def reopen(cls, output, scene, *, flush_bytes: int = DEFAULT_FLUSH_BYTES, keep_partial: bool = True) -> UsdWriter:
        """Continue the partial file of ``output`` left by an earlier run of the same scene."""
        from pxr import Sdf, Tf

        output = Path(os.fspath(output))
        partial = partial_path(output)
        if not partial.exists():
            raise UserError(f"{output}: no partial output {partial} to continue")
        try:
            layer = Sdf.Layer.FindOrOpen(str(partial))
        except Tf.ErrorException as exc:
            raise UserError(f"{partial}: cannot reopen: {_tf_error(exc)}") from None
        targets = []
        for c in scene.curves:
            t = _target(Sdf.Path(c.path), c)
            if not layer.GetAttributeAtPath(t.velocities):  # written with velocities=False
                t.velocities = None
            for attr in (t.points, t.extent):
                if not layer.GetAttributeAtPath(attr):
                    raise UserError(f"{partial}: {c.path}: no {attr.name} spec; not a partial output of this scene")
            targets.append(t)
        writer = cls(layer, output, targets, flush_bytes=flush_bytes, keep_partial=keep_partial)
        qc_root = layer.GetPrimAtPath(QC_ROOT)
        for child in (qc_root.nameChildren if qc_root else []):
            writer._qc[child.name] = {m: child.path.AppendProperty(a) for m, a in ATTRIBUTES.items()
                                      if child.attributes.get(a) is not None}
        return writer

    @classmethod
    def partial_path(cls, output) -> Path:
        return partial_path(output)

    @classmethod
    def check_path(cls, output, input_path=None) -> Path:
        return check_output_path(output, input_path)

    # -- records ----------------------------------------------------------------------------

    def set_record(self, name: str, record: dict) -> None:
        """Store ``record`` in the layer's ``customLayerData`` under ``name``."""
        self.layer.customLayerData = {**dict(self.layer.customLayerData), name: dict(record)}

    def record(self, name: str) -> dict | None:
        value = dict(self.layer.customLayerData).get(name)
        return dict(value) if isinstance(value, dict) else None

    @classmethod
    def read_record(cls, path, name: str) -> dict | None:
        from pxr import Sdf, Tf

        try:
            layer = Sdf.Layer.OpenAsAnonymous(str(path), True)
        except Tf.ErrorException:
            return None
        if layer is None:
            return None
        value = dict(layer.customLayerData).get(name)
        return dict(value) if isinstance(value, dict) else None

    # -- writing ----------------------------------------------------------------------------

    @property
    def is_open(self) -> bool:
        return self.layer is not None

    @property
    def written_time_codes(self) -> list[float]:
        """Time codes every simulated prim has a complete sample at (points, velocities, extent)."""
        common = None
        for t in self.targets:
            for attr in (t.points, t.velocities, t.extent):
                if attr is None:
                    continue
                times = set(self.layer.ListTimeSamplesForPath(attr))
                common = times if common is None else common & times
        return sorted(common or ())

    @property
    def last_time_code(self) -> float | None:
        times = self.written_time_codes
        return times[-1] if times else None

    def write_frame(self, time_code: float, samples) -> None:
        """Author one frame.

        Args:
            time_code: the frame's time code.
            samples: one ``(points, velocities)`` pair per simulated prim, in the order of
                ``scene.curves``: (N, 3) arrays in the prim's local space, stage units and stage
                units per second.
        """
        from pxr import Sdf, UsdGeom

        if len(samples) != len(self.targets):
            raise ValueError(f"expected {len(self.targets)} prims' samples, got {len(samples)}")
        values = []
        for t, (points, velocities) in zip(self.targets, samples):
            # one memory copy each (float64 rounded to float32 on the way), not Vt's per-float FromBuffer
            p = vec3f_array(points)
            v = None if t.velocities is None or velocities is None else vec3f_array(velocities)
            if t.widths is not None:
                e = UsdGeom.Curves.ComputeExtent(p, t.widths)
            else:
                e = UsdGeom.PointBased.ComputeExtent(p)
            values.append((t, p, v, e))
            self._unsaved += (24 if v is not None else 12) * len(p)
        time = float(time_code)
        with Sdf.ChangeBlock():
            for t, p, v, e in values:
                self.layer.SetTimeSample(t.points, time, p)
                if v is not None:
                    self.layer.SetTimeSample(t.velocities, time, v)
                self.layer.SetTimeSample(t.extent, time, e)
        self.frames_written += 1
        if self._unsaved >= self.flush_bytes:
            self.flush()

    def write_qc(self, time_code: float, qc: dict) -> None:
        """Author the frame's QC as time samples on ``/dftl_qc/<prim>`` (:mod:`dftl_warp.output.qc`)."""
        from pxr import Sdf

        time = float(time_code)
        with Sdf.ChangeBlock():
            for prim_path, metrics in qc.items():
                name = qc_prim_name(prim_path)
                specs = self._qc.get(name)
                if specs is None:
                    specs = self._qc[name] = _author_qc_prim(self.layer, name, prim_path)
                for metric, value in metrics.items():
                    if metric not in specs and metric in ATTRIBUTES and value is not None:
                        specs[metric] = _author_qc_attribute(self.layer.GetPrimAtPath(f"{QC_ROOT}/{name}"), metric)
                    if metric in specs and value is not None:
                        self.layer.SetTimeSample(specs[metric], time, int(value) if metric == "nan" else float(value))

    def flush(self) -> None:
        """Save the samples written so far: they move from memory to the partial file."""
        import time

        from pxr import Tf

        start = time.perf_counter()
        try:
            if not self.layer.Save():
                raise UserError(f"{self.output}: cannot write {self.partial}")
        except Tf.ErrorException as exc:
            raise UserError(f"{self.output}: cannot write: {_tf_error(exc)}") from None
        self._unsaved = 0
        self.seconds_saving += time.perf_counter() - start

    # -- finishing --------------------------------------------------------------------------

    def commit(self) -> Path:
        """Save everything and move the result onto the output path; returns it."""
        from pxr import Tf

        self.flush()
        # the value clips of the output this replaces (``shot_clips/``), unless this layer uses them too
        folder = self.output.with_name(self.output.stem + "_clips")
        stale = (f"./{folder.name}/topology.usdc" not in list(self.layer.subLayerPaths)
                 and uses_clips_folder(self.output, folder))
        try:
            if self.output.suffix.lower() == ".usda":
                text = self.partial.with_suffix(".usda")
                try:
                    if not self.layer.Export(str(text)):
                        raise UserError(f"{self.output}: cannot write {text}")
                except Tf.ErrorException as exc:
                    raise UserError(f"{self.output}: cannot write: {_tf_error(exc)}") from None
                replace_file(text, self.output, permissions=True)   # on the disk before it is "done"
                self._close()
                _remove(self.partial)
            else:
                self._close()
                replace_file(self.partial, self.output, permissions=True)
            if stale:  # nothing names them any more: left, they read as part of this output
                import shutil

                shutil.rmtree(folder, ignore_errors=True)
        except OSError as exc:
            self.abort()
            raise UserError(f"{self.output}: cannot write: {exc.strerror or exc}") from None
        except BaseException:
            self.abort()
            raise
        return self.output

    def abort(self) -> None:
        """Drop the partial file (unless ``keep_partial``)."""
        self._close()
        if not self.keep_partial:
            _remove(self.partial)
        _remove(self.partial.with_suffix(".usda"))

    def _close(self) -> None:
        self.layer = None


def uses_clips_folder(path: Path, folder: Path) -> bool:
    """Whether the layer at ``path`` is a value-clips output whose clips are in ``folder`` (it
    sublayers ``./FOLDER/topology.usdc``; docs/caches.md). Reads the layer's metadata only."""
    from pxr import Sdf

    if not folder.is_dir() or not path.is_file():
        return False
    try:
        layer = Sdf.Layer.OpenAsAnonymous(str(path), True)
    except Exception:  # pxr's Tf.ErrorException: not a layer, so not a clips output
        return False
    return layer is not None and f"./{folder.name}/topology.usdc" in list(layer.subLayerPaths)


def _remove(path) -> None:
    try:
        os.remove(path)
    except FileNotFoundError:
        pass


def _target(prim_path, curves) -> _Target:
    from pxr import Vt

    widths = None
    if curves.widths is not None and curves.widths.size:
        widths = Vt.FloatArray.FromNumpy(np.ascontiguousarray(curves.widths, dtype=np.float32))
    return _Target(
        prim=str(prim_path),
        points=prim_path.AppendProperty("points"),
        velocities=prim_path.AppendProperty("velocities"),
        extent=prim_path.AppendProperty("extent"),
        widths=widths,
    )


def _author_qc_prim(layer, name: str, prim_path: str) -> dict:
    """``def Scope "dftl_qc"`` and its ``def Scope "<name>"`` with the QC attributes (custom)."""
    from pxr import Sdf

    root = layer.GetPrimAtPath(QC_ROOT)
    if not root:
        root = Sdf.PrimSpec(layer.pseudoRoot, QC_ROOT.strip("/"), Sdf.SpecifierDef, "Scope")
    prim = Sdf.PrimSpec(root, name, Sdf.SpecifierDef, "Scope")
    label = Sdf.AttributeSpec(prim, "dftl:qc:prim", Sdf.ValueTypeNames.String, Sdf.VariabilityUniform, True)
    label.default = prim_path
    specs = {}
    for metric in ATTRIBUTES:
        if metric != "penetration":  # only where colliders give it (made on its first value)
            specs[metric] = _author_qc_attribute(prim, metric)
    return specs


def _author_qc_attribute(prim, metric: str):
    from pxr import Sdf

    kind = Sdf.ValueTypeNames.Int if metric == "nan" else Sdf.ValueTypeNames.Double
    Sdf.AttributeSpec(prim, ATTRIBUTES[metric], kind, Sdf.VariabilityVarying, True)
    return prim.path.AppendProperty(ATTRIBUTES[metric])


def _author_structure(layer, scene, output: Path, frames, velocities: bool = True) -> list[_Target]:
    """Metadata, sublayer, and the ``over`` prim and attribute specs (no samples yet)."""
    from pxr import Sdf

    info = scene.stage
    targets = []
    with Sdf.ChangeBlock():
        root = layer.pseudoRoot
        root.SetInfo("upAxis", info.up_axis)
        root.SetInfo("metersPerUnit", float(info.meters_per_unit))
        layer.timeCodesPerSecond = float(info.time_codes_per_second)
        if info.frames_per_second is not None:
            layer.framesPerSecond = float(info.frames_per_second)
        if frames is not None:  # the simulated range: the frames that have samples
            layer.startTimeCode = float(frames[0])
            layer.endTimeCode = float(frames[1])
        elif info.start_time_code is not None:
            layer.startTimeCode = float(info.start_time_code)
            layer.endTimeCode = float(info.end_time_code)
        if info.default_prim:
            layer.defaultPrim = info.default_prim
        layer.comment = "Simulated by dftl-warp (Dynamic Follow-The-Leader): time-sampled points, velocities, extent"
        layer.subLayerPaths.append(sublayer_path(scene.source, output))
        for c in scene.curves:
            path = Sdf.Path(c.path)
            prim = Sdf.CreatePrimInLayer(layer, path)
            prim.specifier = Sdf.SpecifierOver
            for name, type_name in (
                ("points", Sdf.ValueTypeNames.Point3fArray),
                ("velocities", Sdf.ValueTypeNames.Vector3fArray),
                ("extent", Sdf.ValueTypeNames.Float3Array),
            ):
                if name == "velocities" and not velocities:
                    continue
                Sdf.AttributeSpec(prim, name, type_name)
            for name in c.normals:
                # authored normals describe the rest shape: blocked (the reader warned)
                spec = Sdf.AttributeSpec(prim, name, Sdf.ValueTypeNames.Normal3fArray)
                spec.default = Sdf.ValueBlock()
            t = _target(path, c)
            if not velocities:
                t.velocities = None
            targets.append(t)
    return targets
