"""Hair previews: ray-traced strands, gprims and meshes on Warp, from USD or numpy.

- :mod:`.scene`: :class:`RenderScene`, what a frame draws;
- :mod:`.usd_scene`: reading a RenderScene and cameras from a USD stage at a time code;
- :mod:`.camera`: the UsdGeom.Camera model, conforming, automatic framing, orbits;
- :mod:`.renderer`: :class:`Renderer` (Warp, ``cpu`` or ``cuda:N``);
- :mod:`.image`: PNG / contact sheet / video output;
- :mod:`.groom`: procedural numpy grooms.
"""

from .camera import Camera, auto_frame
from .renderer import Lighting, Renderer, to_rgba8
from .scene import RenderScene, Shape

__all__ = ["Camera", "auto_frame", "Lighting", "Renderer", "to_rgba8", "RenderScene", "Shape"]
