"""Output: frame writers behind one interface (:mod:`.base`), the USD layer writer (:mod:`.usd`),
the device-side gather of samples (:mod:`.samples`), output locks, paths and progress.

The registered output formats, one line each (:func:`~.base.register_writer`; a writer is chosen
by the output's extension with :func:`~.base.writer_for`):
"""

from .base import WRITERS, FrameWriter, check_output_path, completed, ensure_folder, output_extensions, register_writer, writer_for
from .usd import UsdWriter

register_writer(UsdWriter)  # .usdc, .usda, .usd

__all__ = ["FrameWriter", "WRITERS", "register_writer", "writer_for", "output_extensions", "check_output_path",
           "ensure_folder", "completed", "UsdWriter"]
