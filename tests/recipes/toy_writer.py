# dftl_warp/output/npz.py
"""A toy output format (the writer recipe of docs/architecture.md): every frame's points and
velocities in one ``.npz``, written whole at commit through a partial file."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from .base import FrameWriter, ensure_folder


class NpzWriter(FrameWriter):
    extensions = (".npz",)

    def __init__(self, output: Path, prims: list[str], partial: Path, keep_partial: bool):
        self.output, self.prims, self.partial, self.keep_partial = output, prims, partial, keep_partial
        self.frames: dict[float, list] = {}
        self.records: dict = {}
        self._open = True

    @classmethod
    def create(cls, output, scene, *, frames=None, keep_partial=False):
        output = cls.check_path(output, scene.source)
        ensure_folder(output)
        return cls(output, [c.path for c in scene.curves], cls.partial_path(output), keep_partial)

    def write_frame(self, time_code, samples):
        self.frames[float(time_code)] = [(np.array(p, np.float32), np.array(v, np.float32)) for p, v in samples]

    @property
    def written_time_codes(self):
        return sorted(self.frames)

    @property
    def is_open(self):
        return self._open

    def set_record(self, name, record):
        self.records[name] = dict(record)

    def record(self, name):
        return self.records.get(name)

    @classmethod
    def read_record(cls, path, name):
        try:
            with np.load(path) as data:
                return json.loads(str(data["records"])).get(name)
        except (OSError, KeyError, ValueError):
            return None

    def commit(self):
        times = self.written_time_codes
        arrays = {"time_codes": np.array(times), "prims": np.array(self.prims), "records": np.array(json.dumps(self.records))}
        for k, prim in enumerate(self.prims):
            arrays[f"points{k}"] = np.stack([self.frames[t][k][0] for t in times])
            arrays[f"velocities{k}"] = np.stack([self.frames[t][k][1] for t in times])
        with open(self.partial, "wb") as f:
            np.savez(f, **arrays)
        os.replace(self.partial, self.output)
        self._open = False
        return self.output

    def abort(self):
        self._open = False
        if not self.keep_partial and self.partial.exists():
            os.remove(self.partial)
