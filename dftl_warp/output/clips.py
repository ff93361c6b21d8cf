"""USD value clips output (``simulate --clips [FRAMES]``, UsdClipsAPI; docs/caches.md).

``OUTPUT`` (e.g. ``shot.usdc``) is a small layer that sublayers a topology layer and the input and
holds, on each simulated prim, the clip set ``default``: ``assetPaths`` (one crate layer per chunk
of FRAMES frames), ``primPath``, ``active``, ``times`` and ``manifestAssetPath``. Every USD
consumer therefore sees one animated stage. Next to it, in ``shot_clips/``:

- ``topology.usdc``: the ``over`` prims and the attribute specs (points, velocities, extent), no
  samples: the topology layer (sublayered by the output) and the clips' manifest
  (``manifestAssetPath``);
- ``clip.NNNN.usdc``: the time samples of chunk NNNN.

Frames are gathered per chunk; a full chunk is handed to a pool of writer threads, each of which
authors and saves its own crate layer while the frame loop goes on. Everything is written under
hidden partial names and moved into place by :meth:`ClipsWriter.commit` (the output layer last),
so an interrupted run leaves no output. Records and QC live in the output layer.
"""

from __future__ import annotations

import os
import shutil
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ..errors import UserError
from .base import FrameWriter, ensure_folder
from .usd import UsdWriter, check_output_path

#: the clip set's name
CLIP_SET = "default"
#: ``--clips`` with no value: frames per clip chosen so that a clip holds about this many bytes
AUTO_CLIP_BYTES = 256 << 20
#: parallel clip writers
WRITERS = 4


def clips_folder(output: Path) -> Path:
    return output.with_name(output.stem + "_clips")


def auto_clip_frames(scene, velocities: bool = True) -> int:
    points = sum(c.num_points for c in scene.curves)
    per_frame = max(1, points * (24 if velocities else 12))
    return max(1, AUTO_CLIP_BYTES // per_frame)


def _write_clip(path: Path, scene_paths, frames, velocities: bool) -> None:
    """One crate layer with the samples of ``frames``: [(time, [(points, velocities), ...])]."""
    from pxr import Sdf, UsdGeom, Vt

    layer = Sdf.Layer.CreateNew(str(path))
    with Sdf.ChangeBlock():
        specs = []
        for prim_path, widths in scene_paths:
            prim = Sdf.CreatePrimInLayer(layer, prim_path)
            prim.specifier = Sdf.SpecifierOver
            names = [("points", Sdf.ValueTypeNames.Point3fArray), ("extent", Sdf.ValueTypeNames.Float3Array)]
            if velocities:
                names.append(("velocities", Sdf.ValueTypeNames.Vector3fArray))
            for name, kind in names:
                Sdf.AttributeSpec(prim, name, kind)
            specs.append((Sdf.Path(prim_path), widths))
        for time, samples in frames:
            for (path_, widths), (p, v) in zip(specs, samples):
                pts = Vt.Vec3fArray.FromNumpy(p)
                layer.SetTimeSample(path_.AppendProperty("points"), time, pts)
                e = UsdGeom.Curves.ComputeExtent(pts, widths) if widths is not None else UsdGeom.PointBased.ComputeExtent(pts)
                layer.SetTimeSample(path_.AppendProperty("extent"), time, e)
                if velocities and v is not None:
                    layer.SetTimeSample(path_.AppendProperty("velocities"), time, Vt.Vec3fArray.FromNumpy(v))
    if not layer.Save():
        raise UserError(f"cannot write {path}")


class ClipsWriter(FrameWriter):
    """The :class:`FrameWriter` of a value-clips output (made by :func:`create_clips`)."""

    resumable = False

    def __init__(self, output: Path, scene, frames, clip_frames: int, velocities: bool):
        self.output = output
        self.scene = scene
        self.first, self.last = frames
        self.clip_frames = int(clip_frames)
        self.velocities = velocities
        self.folder = clips_folder(output)
        self.partial_folder = output.with_name(f".{self.folder.name}.dftl-partial")
        shutil.rmtree(self.partial_folder, ignore_errors=True)
        self.partial_folder.mkdir()
        # the output layer: metadata, sublayers, over specs, records and QC (a UsdWriter's layer)
        self.top = UsdWriter.create(output, scene, frames=frames, velocities=velocities)
        self.targets = [(c.path, t.widths) for c, t in zip(scene.curves, self.top.targets)]
        self._chunk: list = []
        self._chunk_index = None
        self._clips: list[tuple[int, int, int]] = []  # (index, first time, last time)
        self._pool = ThreadPoolExecutor(WRITERS, thread_name_prefix="dftl-clip")
        self._futures = []
        self._written: list[float] = []

    def _clip_name(self, index: int) -> str:
        return f"clip.{index:04d}.usdc"

    def write_frame(self, time_code: float, samples) -> None:
        index = (int(round(time_code)) - self.first) // self.clip_frames
        if self._chunk and index != self._chunk_index:
            self._submit()
        self._chunk_index = index
        owned = [(np.array(p, dtype=np.float32, copy=True).reshape(-1, 3),
                  None if v is None else np.array(v, dtype=np.float32, copy=True).reshape(-1, 3)) for p, v in samples]
        self._chunk.append((float(time_code), owned))
        self._written.append(float(time_code))

    def _submit(self) -> None:
        frames, index = self._chunk, self._chunk_index
        self._chunk = []
        self._clips.append((index, frames[0][0], frames[-1][0]))
        path = self.partial_folder / self._clip_name(index)
        self._futures.append(self._pool.submit(_write_clip, path, self.targets, frames, self.velocities))

    def write_qc(self, time_code: float, qc: dict) -> None:
        self.top.write_qc(time_code, qc)

    def flush(self) -> None:
        for f in self._futures:
            f.result()

    @property
    def written_time_codes(self) -> list[float]:
        return list(self._written)

    @property
    def is_open(self) -> bool:
        return self.top is not None

    def set_record(self, name: str, record: dict) -> None:
        self.top.set_record(name, record)

    def record(self, name: str) -> dict | None:
        return self.top.record(name)

    @classmethod
    def read_record(cls, path, name: str) -> dict | None:
        return UsdWriter.read_record(path, name)

    def commit(self) -> Path:
        from pxr import Sdf, Vt

        try:
            if self._chunk:
                self._submit()
            self._pool.shutdown(wait=True)
            self.flush()
            # topology: the top layer's over specs without samples (and without records or QC)
            topology = Sdf.Layer.CreateNew(str(self.partial_folder / "topology.usdc"))
            for path_, _ in self.targets:
                Sdf.CreatePrimInLayer(topology, path_).specifier = Sdf.SpecifierOver
                Sdf.CopySpec(self.top.layer, path_, topology, path_)
            topology.Save()
            layer = self.top.layer
            rel = f"./{self.folder.name}"
            layer.subLayerPaths.insert(0, f"{rel}/topology.usdc")
            for path_, _ in self.targets:  # the samples come from the clips; the specs from the topology
                prim = layer.GetPrimAtPath(path_)
                for name in ("points", "velocities", "extent"):
                    attr = prim.attributes.get(name)
                    if attr is not None:
                        prim.RemoveProperty(attr)
            # the clip metadata (UsdClipsAPI's ``clips`` dictionary), authored with Sdf: no stage is
            # opened on the partial layer, whose relative paths resolve only once it is in place
            assets = Sdf.AssetPathArray([f"{rel}/{self._clip_name(i)}" for i, _, _ in self._clips])
            active = Vt.Vec2dArray([(t0, float(k)) for k, (_, t0, _) in enumerate(self._clips)])
            times = []
            for _, t0, t1 in self._clips:
                times += [(t0, t0)] + ([(t1, t1)] if t1 != t0 else [])
            for path_, _ in self.targets:
                layer.GetPrimAtPath(path_).SetInfo("clips", {CLIP_SET: {
                    "assetPaths": assets, "primPath": path_, "active": active, "times": Vt.Vec2dArray(times),
                    "manifestAssetPath": Sdf.AssetPath(f"{rel}/topology.usdc")}})  # topology = manifest
            shutil.rmtree(self.folder, ignore_errors=True)
            os.replace(self.partial_folder, self.folder)
            out = self.top.commit()
            self.top = None
            return out
        except BaseException:
            self.abort()
            raise

    def abort(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)
        if self.top is not None and self.top.is_open:
            self.top.abort()
        self.top = None
        shutil.rmtree(self.partial_folder, ignore_errors=True)


def create_clips(output, scene, *, frames, clip_frames: int = 0, velocities: bool = True) -> ClipsWriter:
    """A :class:`ClipsWriter` for ``output`` (``clip_frames`` 0: :func:`auto_clip_frames`)."""
    output = check_output_path(output, scene.source)
    if output.suffix.lower() == ".usda":
        raise UserError(f"{output}: --clips writes a .usdc or .usd output layer")
    ensure_folder(output)
    frames = (int(frames[0]), int(frames[1]))
    return ClipsWriter(output, scene, frames, clip_frames or auto_clip_frames(scene, velocities), velocities)
