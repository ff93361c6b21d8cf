#!/usr/bin/env python3
"""A groom at rest with hair-hair interaction: does it keep its shape? Simulates a groom USD as
authored, with ``dftl:hairHair`` on and ``dftl:hairHairThreshold`` 0 (all the density pushes), and
with ``dftl:hairHair`` alone (the default threshold: the densest node at rest, which ``dftl-warp
info`` prints), each with ``dftl-warp simulate``'s defaults; prints
each run's median tip displacement from the first frame to the last (stage units) and renders the
first and last frames side by side into ``--out``/hair-hair-rest-sheet.png (rows: the runs).

    python scripts/hair_hair_rest_sheet.py /path/to/Bangs_100_head.usda --out docs/img
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw
from pxr import Sdf, Usd, UsdGeom

from dftl_warp import cli
from dftl_warp.commands.info import describe
from dftl_warp.usd.read import read_scene


def variant(src: Path, out: Path, hair_hair: bool, threshold: float | None = None) -> Path:
    """A copy of ``src``, with hair-hair on the scene's holder prim (and ``threshold`` where not None)."""
    stage = Usd.Stage.Open(str(src))
    stage.GetRootLayer().Export(str(out))
    if not hair_hair:
        return out
    stage = Usd.Stage.Open(str(out))
    scenes = [p for p in stage.Traverse() if p.GetTypeName() == "PhysicsScene"]
    holder = scenes[0] if scenes else stage.GetDefaultPrim()
    holder.CreateAttribute("dftl:hairHair", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    if threshold is not None:
        holder.CreateAttribute("dftl:hairHairThreshold", Sdf.ValueTypeNames.Float, custom=True).Set(float(threshold))
    stage.Save()
    return out


def tip_motion(path: Path, first: int, last: int) -> float:
    """Median tip displacement (stage units) of every curves prim's strands from ``first`` to ``last``."""
    stage = Usd.Stage.Open(str(path))
    moved = []
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.BasisCurves):
            c = UsdGeom.BasisCurves(prim)
            tips = np.cumsum(np.array(c.GetCurveVertexCountsAttr().Get())) - 1
            a, b = np.array(c.GetPointsAttr().Get(first)), np.array(c.GetPointsAttr().Get(last))
            moved.append(np.linalg.norm(b[tips] - a[tips], axis=1))
    return float(np.median(np.concatenate(moved)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("groom")
    ap.add_argument("--out", default=".")
    args = ap.parse_args(argv)
    src = Path(args.groom)
    work = Path(tempfile.mkdtemp(prefix="hh_rest_"))
    hh = variant(src, work / "hh.usda", True)
    peak = describe(read_scene(str(hh)))["hair_hair"][0]["rest_peak"]
    runs = [("no hair-hair", False, None), ("hair-hair, threshold 0", True, 0.0),
            (f"hair-hair, default threshold {peak:.3g} (the densest node at rest)", True, None)]
    panels, size = [], 400
    for k, (label, hair_hair, threshold) in enumerate(runs):
        stage = variant(src, work / f"run{k}.usda", hair_hair, threshold)
        out = work / f"run{k}.usdc"
        assert cli.main(["simulate", str(stage), "-o", str(out), "-q"]) == 0
        st = Usd.Stage.Open(str(out))
        first, last = int(st.GetStartTimeCode()), int(st.GetEndTimeCode())
        print(f"{label}: median tip displacement from frame {first} to {last}: {tip_motion(out, first, last):.4g} "
              "units", flush=True)
        row = []
        for frame in (first, last):
            png = work / f"run{k}_{frame}.png"
            assert cli.main(["render", str(out), "--frame", str(frame), "--resolution", f"{size}x{size}",
                             "--spp", "4", "-o", str(png), "-q"]) == 0
            row.append((f"{label}, frame {frame}", Image.open(png).convert("RGB")))
        panels.append(row)
    sheet = Image.new("RGB", (2 * size, len(panels) * (size + 20)), "white")
    draw = ImageDraw.Draw(sheet)
    for r, row in enumerate(panels):
        for c, (label, image) in enumerate(row):
            sheet.paste(image, (c * size, r * (size + 20) + 20))
            draw.text((c * size + 5, r * (size + 20) + 4), label, fill="black")
    Path(args.out).mkdir(parents=True, exist_ok=True)
    sheet.save(Path(args.out) / "hair-hair-rest-sheet.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
