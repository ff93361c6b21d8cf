"""Writing frames: PNG (RGBA, straight alpha), contact sheets, MP4/GIF. Every file is written
to a temporary name in its folder and renamed into place, so no half-written file is left."""

from __future__ import annotations

import math
import os
import re
import tempfile
from pathlib import Path

import numpy as np

from ..durable import replace_file
from ..errors import UserError

VIDEO_SUFFIXES = (".mp4", ".gif", ".mov", ".webm")


def _atomic(path, write):
    """Run ``write(tmp)`` on a temporary file next to ``path``, then rename it onto ``path``.
    The folder is created if missing. Any OSError (unwritable folder, full disk) becomes a
    one-line UserError and leaves no file behind."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
        os.close(fd)
    except OSError as exc:
        raise UserError(f"{path}: cannot write: {exc.strerror or exc}") from None
    try:
        write(tmp)
        replace_file(tmp, path, permissions=True)  # on the disk, then renamed (mkstemp's 0600 made usual)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise UserError(f"{path}: cannot write: {exc.strerror or exc}") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def check_video(path) -> None:
    """UserError now (before any rendering) when a video ``path`` cannot be written here:
    imageio (and for anything but GIF, imageio-ffmpeg) from the ``video`` extra is missing."""
    suffix = Path(path).suffix.lower()
    try:
        import imageio.v3  # noqa: F401
    except ImportError:
        raise UserError(f"{path}: writing a video needs imageio: pip install 'dftl-warp[video]'") from None
    if suffix != ".gif":
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            raise UserError(f"{path}: writing {suffix} needs imageio-ffmpeg: pip install 'dftl-warp[video]'") from None


def check_fps(fps) -> None:
    """ValueError unless ``fps`` is a positive, finite number of frames per second."""
    if not (isinstance(fps, (int, float, np.number)) and math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps {fps!r}: must be a positive, finite number of frames per second")


def write_png(path, rgba8: np.ndarray) -> None:
    """Write an (H, W, 4) uint8 straight-alpha image as an RGBA PNG."""
    from PIL import Image

    _atomic(path, lambda tmp: Image.fromarray(np.ascontiguousarray(rgba8), "RGBA").save(tmp, format="PNG"))


def read_png(path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGBA"))


def frame_path(pattern: str, frame: float) -> str:
    """``pattern`` with its run of '#' replaced by the zero-padded frame number. A pattern names
    whole frames only (sequence tools read ``hair.0001.png``, not ``hair.0001.5.png``): a
    fractional ``frame`` raises ValueError."""
    m = re.search(r"#+", pattern)
    if not m:
        return pattern
    if not is_whole(frame):
        raise ValueError(f"{pattern}: frame {frame:g} is not a whole number: a '#' pattern numbers images by frame")
    width = len(m.group(0))
    return pattern[: m.start()] + f"{int(round(frame)):0{width}d}" + pattern[m.end():]


def is_whole(frame) -> bool:
    """True for a finite frame number without a fractional part (within 1e-6)."""
    return math.isfinite(frame) and abs(frame - round(frame)) <= 1e-6


def has_pattern(path: str) -> bool:
    return "#" in path


def contact_sheet(frames, columns: int | None = None, gap: int = 4) -> np.ndarray:
    """One RGBA image of ``frames`` (same-size uint8 RGBA) on a grid, transparent between."""
    n = len(frames)
    columns = columns or max(1, math.ceil(math.sqrt(n)))
    rows = math.ceil(n / columns)
    h, w = frames[0].shape[:2]
    sheet = np.zeros((rows * h + (rows - 1) * gap, columns * w + (columns - 1) * gap, 4), dtype=np.uint8)
    for k, f in enumerate(frames):
        r, c = divmod(k, columns)
        sheet[r * (h + gap): r * (h + gap) + h, c * (w + gap): c * (w + gap) + w] = f
    return sheet


def over_background(rgba8: np.ndarray, background=(40, 40, 46)) -> np.ndarray:
    """RGB uint8 of a straight-alpha frame composited over a flat colour (for videos)."""
    a = rgba8[..., 3:4].astype(np.float64) / 255.0
    rgb = rgba8[..., :3].astype(np.float64) * a + np.asarray(background, dtype=np.float64) * (1.0 - a)
    return np.round(rgb).astype(np.uint8)


def write_video(path, frames, fps: float = 24.0) -> None:
    """MP4/GIF/... of RGBA frames over a dark background, through imageio (extra ``video``).
    ``fps`` must be a positive, finite number (ValueError otherwise)."""
    check_fps(fps)
    try:
        import imageio.v3 as iio
    except ImportError:
        raise UserError(f"{path}: writing a video needs imageio: pip install 'dftl-warp[video]'") from None
    rgb = np.stack([over_background(f) for f in frames])
    suffix = Path(path).suffix.lower()

    def write(tmp):
        if suffix == ".gif":
            iio.imwrite(tmp, rgb, extension=".gif", duration=1000.0 / fps, loop=0)
        else:
            try:
                iio.imwrite(tmp, rgb, extension=suffix, fps=fps, codec="libx264" if suffix == ".mp4" else None,
                            macro_block_size=2)
            except (ImportError, ValueError, RuntimeError) as exc:
                raise UserError(f"{path}: cannot write {suffix} ({exc}); pip install 'dftl-warp[video]' (imageio-ffmpeg)") from None

    _atomic(path, write)
