"""The Warp hair renderer: a :class:`RenderScene` and a :class:`Camera` in, linear RGBA out.

The strand BVH (``wp.Bvh`` over segment boxes) is kept between frames: when a new frame has
the same strand topology, the segment boxes are rewritten on the device and the tree is refit
(``bvh.refit()``) instead of rebuilt. ``Renderer.bvh_builds`` / ``bvh_refits`` count both;
``Renderer.hair_visible`` says whether the last image shows any strand. The boxes enclose the
strands as drawn for the camera: widened to ``min_pixel_width`` pixels at their depth, seen at
opacity true / drawn width (:mod:`dftl_warp.kernels.render.pixel`).

Bad arguments (a resolution of 8.5 or 0 pixels, a fractional ``spp``, a negative
``min_pixel_width``, an unknown shading or conform policy, a bad :class:`Camera` or
:class:`Lighting` field) raise :class:`~dftl_warp.options.OptionError`: a ValueError for scripts, one
line for ``dftl-warp render``; nothing is truncated to an integer.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import warp as wp

from ..core.devices import device_argument
from ..core.layout import strand_offsets
from ..kernels.render import pixel
from ..kernels.render import tracer as rk
from ..options import OptionError
from ..usd.values import number
from .camera import CONFORM_POLICIES, Camera, auto_frame
from .scene import RenderScene

SHADINGS = {"marschner": 0, "kajiya-kay": 1}
#: the largest image width or height, in pixels (``dftl-warp render --resolution``)
MAX_SIDE = 16384
#: the most samples per pixel (``--spp``; 8 by default, 64 in the comparisons of docs/render.md)
MAX_SPP = 4096
#: the default minimum width of a drawn strand, in pixels (``--min-pixel-width``; 0: true widths)
MIN_PIXEL_WIDTH = 1.0
#: the largest minimum pixel width
MAX_PIXEL_WIDTH = 64.0


@dataclass
class Lighting:
    """Camera-relative lights. Directions point towards the light in camera space (x right,
    y up, z towards the viewer); colours are linear irradiance (key, fill) and radiance
    (ambient)."""

    key_dir: tuple = (-0.55, 0.70, 0.45)
    key_color: tuple = (3.4, 3.25, 3.0)
    fill_dir: tuple = (0.80, 0.05, 0.35)
    fill_color: tuple = (0.40, 0.46, 0.58)
    ambient: tuple = (0.07, 0.075, 0.085)
    hair_shadow_transmittance: float = 0.6
    roughness: float = 0.25
    geometry_albedo: tuple = (0.45, 0.45, 0.45)

    def __post_init__(self):
        self.check()

    def check(self) -> None:
        """OptionError (a ValueError) naming the first bad field: a direction that is not 3 finite
        numbers or is zero (its pixels came out NaN), a colour or albedo that is not 3 finite,
        non-negative numbers, a transmittance outside 0..1, a negative or non-finite roughness."""
        for name in ("key_dir", "fill_dir"):
            v = _vector3(name, getattr(self, name))
            if not np.any(v):
                raise OptionError(f"lighting {name} {_shown3(v)}: must be a nonzero vector")
        for name in ("key_color", "fill_color", "ambient", "geometry_albedo"):
            v = _vector3(name, getattr(self, name))
            if (v < 0).any():
                raise OptionError(f"lighting {name} {_shown3(v)}: must not be negative")
        t = number(self.hair_shadow_transmittance, "lighting hair_shadow_transmittance", error=OptionError, finite=True)
        if not 0 <= t <= 1:
            raise OptionError(f"lighting hair_shadow_transmittance = {t:g}: must be from 0 to 1")
        if number(self.roughness, "lighting roughness", error=OptionError, finite=True) < 0:
            raise OptionError(f"lighting roughness = {self.roughness:g}: must be >= 0")


def _shown3(v) -> str:
    return "(" + ", ".join(f"{x:g}" for x in v) + ")"


def _vector3(name: str, value) -> np.ndarray:
    """``value`` as 3 finite floats; OptionError naming the lighting field ``name`` otherwise."""
    try:
        v = None if isinstance(value, (str, bytes)) else np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        v = None
    if v is None or v.shape != (3,) or np.asarray(value).dtype == np.bool_:
        raise OptionError(f"lighting {name} {value!r}: expected 3 numbers")
    if not np.isfinite(v).all():
        raise OptionError(f"lighting {name} {_shown3(v)}: must be finite")
    return v


def parse_device(name: str) -> str:
    """A Warp device name, checked; raises OptionError (a UserError) for one this machine lacks."""
    return str(device_argument(name, OptionError))


def pixel_width(name: str, value) -> float:
    """``value`` as a minimum strand width in pixels, 0 (off) to :data:`MAX_PIXEL_WIDTH`; OptionError
    naming ``name`` for anything else (a string, a bool, nan, a negative width)."""
    numeric = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    if not numeric or not math.isfinite(value) or not 0 <= value <= MAX_PIXEL_WIDTH:
        raise OptionError(f"{name} {value!r}: expected a width in pixels from 0 (off) to {MAX_PIXEL_WIDTH:g}")
    return float(value)


def whole_number(name: str, value, low: int = 1, high: int | None = None) -> int:
    """``value`` as an int in [``low``, ``high``]; OptionError naming ``name`` for a fraction
    (8.5 is refused, not cut to 8), a bool, a string or a number out of range."""
    numeric = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    if not numeric or not math.isfinite(value) or value != int(value):
        raise OptionError(f"{name} {value!r}: expected a whole number")
    if value < low:
        raise OptionError(f"{name} {value!r}: must be at least {low}")
    if high is not None and value > high:
        raise OptionError(f"{name} {value!r}: must be at most {high}")
    return int(value)


class Renderer:
    """Renders frames of ``width`` x ``height`` pixels with ``spp`` samples per pixel on a Warp
    ``device``; on the CPU, ``threads`` threads (default: all cores) render bands of rows.

    ``min_pixel_width``: a strand thinner than this many pixels at its depth is drawn that wide,
    with its opacity scaled by true / drawn width, so the coverage (how much hair is seen) stays
    that of the true widths while thin hair no longer breaks into aliased dots; 0: true widths."""

    def __init__(self, width=640, height=480, spp=4, device="cpu", shading="marschner",
                 conform="expandAperture", lighting: Lighting | None = None, seed=0, threads=None,
                 min_pixel_width=MIN_PIXEL_WIDTH):
        self.width = whole_number("width", width, 1, MAX_SIDE)
        self.height = whole_number("height", height, 1, MAX_SIDE)
        self.spp = whole_number("spp", spp, 1, MAX_SPP)
        self.min_pixel_width = pixel_width("min_pixel_width", min_pixel_width)
        if shading not in SHADINGS:
            raise OptionError(f"shading {shading!r}: choose one of {', '.join(SHADINGS)}")
        if conform not in CONFORM_POLICIES:
            raise OptionError(f"conform {conform!r}: choose one of {', '.join(CONFORM_POLICIES)}")
        if lighting is not None and not isinstance(lighting, Lighting):
            raise TypeError(f"lighting must be a Lighting or None, got {type(lighting).__name__}")
        self.device = parse_device(device)
        self.shading = shading
        self.conform = conform
        self.lighting = lighting or Lighting()
        self.seed = whole_number("seed", seed, 0, 2**31 - 1)
        #: CPU threads rendering bands of rows (default: all cores); one launch on CUDA
        threads = None if threads is None else whole_number("threads", threads)
        self.threads = 1 if wp.get_device(self.device).is_cuda else threads or os.cpu_count() or 1
        self.bvh_builds = 0
        self.bvh_refits = 0
        #: whether a sample of the last :meth:`render` saw a strand first (None before any);
        #: False: the camera sees no strand (it looks away, or they are clipped, hidden or too thin)
        self.hair_visible = None
        self._hair_counts = None
        self._hair = None
        self._image = wp.zeros((self.height, self.width), dtype=wp.vec4, device=self.device)
        self._hair_seen = wp.zeros(1, dtype=wp.int32, device=self.device)

    # -- scene upload --------------------------------------------------------------------
    def _upload_hair(self, scene: RenderScene, origin: np.ndarray):
        """Strand arrays on the device; the segment tree is fitted by :meth:`_fit_hair`."""
        dev = self.device
        counts = np.asarray(scene.curve_vertex_counts, dtype=np.int64)
        pts = (np.asarray(scene.points, dtype=np.float64) - origin).astype(np.float32)
        radii = np.asarray(scene.radii, dtype=np.float32)
        colors = np.asarray(scene.colors, dtype=np.float32)
        hair = rk.RenderHair()
        self._new_tree = False
        if scene.segment_count == 0:
            hair.count = 0
            hair.bvh = wp.uint64(0)
            empty_i = wp.zeros(1, dtype=wp.int32, device=dev)
            hair.seg_v0 = hair.seg_strand = empty_i
            hair.points = hair.colors = wp.zeros(1, dtype=wp.vec3, device=dev)
            hair.radii = hair.drawn = wp.zeros(1, dtype=float, device=dev)
            self._hair, self._hair_counts = hair, None
            return
        if self._hair is not None and self._hair_counts is not None and np.array_equal(self._hair_counts, counts):
            # same topology: new positions, radii and colours; the tree is refit
            hair = self._hair
            hair.points.assign(pts)
            hair.radii.assign(radii)
            hair.colors.assign(colors)
            return
        starts = strand_offsets(counts)
        seg_counts = np.maximum(counts - 1, 0)
        seg_strand = np.repeat(np.arange(len(counts)), seg_counts)
        seg_v0 = starts[seg_strand] + (np.arange(int(seg_counts.sum())) - np.repeat(strand_offsets(seg_counts), seg_counts))
        self._n_seg = len(seg_v0)
        hair.count = self._n_seg
        hair.seg_v0 = wp.array(seg_v0.astype(np.int32), dtype=wp.int32, device=dev)
        hair.seg_strand = wp.array(seg_strand.astype(np.int32), dtype=wp.int32, device=dev)
        hair.points = wp.array(pts, dtype=wp.vec3, device=dev)
        hair.radii = wp.array(radii, dtype=float, device=dev)
        hair.drawn = wp.empty(len(radii), dtype=float, device=dev)
        hair.colors = wp.array(colors, dtype=wp.vec3, device=dev)
        self._lowers = wp.empty(self._n_seg, dtype=wp.vec3, device=dev)
        self._uppers = wp.empty(self._n_seg, dtype=wp.vec3, device=dev)
        self._hair, self._hair_counts = hair, counts.copy()
        self._new_tree = True

    def _fit_hair(self, cam: rk.RenderCamera, world_from_camera: np.ndarray):
        """Drawn radii for this camera (the true radii widened to ``min_pixel_width`` at their
        depth), the segment boxes around them, and the tree built (new topology) or refit."""
        hair, dev = self._hair, self.device
        if hair.count == 0:
            return
        if self.min_pixel_width > 0:
            left, right, bottom, top = (float(v) for v in cam.window)
            # world size of a pixel at camera depth 1 (orthographic: anywhere)
            pixel = max(np.linalg.norm(world_from_camera[:3, 0]) * (right - left) / self.width,
                        np.linalg.norm(world_from_camera[:3, 1]) * (top - bottom) / self.height)
            camera_from_world = wp.mat44(*np.linalg.inv(world_from_camera).astype(np.float32).reshape(-1))
            wp.launch(rk.widen_radii, dim=len(hair.radii), device=dev,
                      inputs=[camera_from_world, cam.orthographic, float(0.5 * self.min_pixel_width * pixel),
                              hair.radii, hair.points, hair.drawn])
        else:
            wp.copy(hair.drawn, hair.radii)
        wp.launch(rk.segment_bounds, dim=self._n_seg,
                  inputs=[hair.seg_v0, hair.points, hair.drawn, self._lowers, self._uppers], device=dev)
        if self._new_tree:
            self._bvh = wp.Bvh(self._lowers, self._uppers)
            self.bvh_builds += 1
            hair.bvh = self._bvh.id
            self._new_tree = False
        else:
            self._bvh.refit()
            self.bvh_refits += 1

    def _upload_shapes(self, scene: RenderScene, origin: np.ndarray):
        dev = self.device
        shapes = rk.RenderShapes()
        n = len(scene.shapes)
        shapes.count = n
        kinds = np.array([s.kind for s in scene.shapes] or [0], dtype=np.int32)
        mats = np.zeros((max(n, 1), 4, 4), dtype=np.float32)
        params = np.zeros((max(n, 1), 3), dtype=np.float32)
        shift = np.eye(4)
        shift[:3, 3] = -origin
        for i, s in enumerate(scene.shapes):
            mats[i] = np.linalg.inv(shift @ np.asarray(s.world_from_local, dtype=np.float64))
            params[i] = s.params
        shapes.kind = wp.array(kinds, dtype=wp.int32, device=dev)
        shapes.local_from_world = wp.array(mats, dtype=wp.mat44, device=dev)
        shapes.params = wp.array(params, dtype=wp.vec3, device=dev)
        if len(scene.mesh_triangles):
            pts = (np.asarray(scene.mesh_points, dtype=np.float64) - origin).astype(np.float32)
            self._mesh = wp.Mesh(points=wp.array(pts, dtype=wp.vec3, device=dev),
                                 indices=wp.array(np.asarray(scene.mesh_triangles, dtype=np.int32).reshape(-1), dtype=wp.int32, device=dev))
            shapes.mesh = self._mesh.id
            shapes.has_mesh = 1
        else:
            self._mesh = None
            shapes.mesh = wp.uint64(0)
            shapes.has_mesh = 0
        self._shapes = shapes

    # -- camera and lights ---------------------------------------------------------------
    def _camera(self, camera: Camera, origin: np.ndarray):
        """The kernels' camera, and its world_from_camera (float64) relative to ``origin``."""
        cam = rk.RenderCamera()
        m = np.asarray(camera.world_from_camera, dtype=np.float64).copy()
        m[:3, 3] -= origin
        cam.world_from_camera = wp.mat44(*m.astype(np.float32).reshape(-1))
        cam.window = wp.vec4(*np.asarray(camera.screen_window(self.width, self.height, self.conform), dtype=np.float32))
        cam.near, cam.far = float(camera.near), float(camera.far)
        cam.orthographic = 1 if camera.projection == "orthographic" else 0
        cam.width, cam.height = self.width, self.height
        return cam, m

    def _lights(self, camera: Camera) -> rk.RenderLights:
        lt = self.lighting
        rot = np.asarray(camera.world_from_camera, dtype=np.float64)[:3, :3]

        def to_world(d):
            v = rot @ (np.asarray(d, dtype=np.float64) / np.linalg.norm(d))
            return wp.vec3(*(v / np.linalg.norm(v)))

        out = rk.RenderLights()
        out.key_dir, out.fill_dir = to_world(lt.key_dir), to_world(lt.fill_dir)
        out.key_color, out.fill_color = wp.vec3(*lt.key_color), wp.vec3(*lt.fill_color)
        out.ambient = wp.vec3(*lt.ambient)
        out.hair_shadow_transmittance = float(lt.hair_shadow_transmittance)
        out.shading = SHADINGS[self.shading]
        out.roughness = float(lt.roughness)
        out.geometry_albedo = wp.vec3(*lt.geometry_albedo)
        return out

    # -- rendering -----------------------------------------------------------------------
    def default_camera(self, scene: RenderScene) -> Camera:
        """Automatic framing of the hair's bounds (of everything, without hair)."""
        return auto_frame(scene.hair_bounds() or scene.bounds(), self.width, self.height, scene.up_axis)

    def render(self, scene: RenderScene, camera: Camera | None = None) -> np.ndarray:
        """(height, width, 4) float32: linear straight colour and alpha = coverage. ValueError
        (:meth:`RenderScene.check`) when the scene's arrays do not fit together; OptionError (a
        ValueError) for a bad camera (:meth:`Camera.check`) or lighting (:meth:`Lighting.check`)."""
        if not isinstance(scene, RenderScene):
            raise TypeError(f"scene must be a RenderScene, got {type(scene).__name__}")
        if camera is not None and not isinstance(camera, Camera):
            raise TypeError(f"camera must be a Camera or None, got {type(camera).__name__}")
        scene.check()
        if camera is None:
            camera = self.default_camera(scene)
        camera.check()   # again: its fields may have been set since it was built
        self.lighting.check()
        bounds = scene.bounds()
        origin = np.zeros(3) if bounds is None else 0.5 * (bounds[0] + bounds[1])
        cam, world_from_camera = self._camera(camera, origin)
        self._upload_hair(scene, origin)
        self._fit_hair(cam, world_from_camera)
        self._upload_shapes(scene, origin)
        inputs = [cam, self._hair, self._shapes, self._lights(camera), self.spp, self.seed]
        outputs = [self._image, self._hair_seen]
        self._hair_seen.zero_()
        if self.threads <= 1 or self.height < 2:
            wp.launch(pixel.render_kernel, dim=(self.height, self.width), inputs=[*inputs, 0],
                      outputs=outputs, device=self.device)
        else:
            # Warp runs a CPU launch on one thread (and lets go of the GIL): render bands of
            # rows concurrently, small bands handed out in turn to even out the work
            band = max(1, min(16, self.height // (4 * self.threads)))

            def launch(row):
                rows = min(band, self.height - row)
                wp.launch(pixel.render_kernel, dim=(rows, self.width), inputs=[*inputs, row],
                          outputs=outputs, device=self.device)

            with ThreadPoolExecutor(self.threads) as pool:
                list(pool.map(launch, range(0, self.height, band)))
        self.hair_visible = bool(self._hair_seen.numpy()[0])
        return self._image.numpy().copy()


def to_rgba8(image: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Linear straight RGBA float -> sRGB-encoded straight RGBA uint8 (colour 0 where alpha is 0).

    Highlights roll off smoothly above 0.8 instead of clipping."""
    rgb = np.asarray(image[..., :3], dtype=np.float64) * exposure
    knee = 0.8
    over = np.maximum(rgb - knee, 0.0)
    rgb = np.where(rgb > knee, knee + (1.0 - knee) * (1.0 - np.exp(-over / (1.0 - knee))), rgb)
    rgb = np.clip(rgb, 0.0, 1.0)
    srgb = np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * np.power(rgb, 1.0 / 2.4) - 0.055)
    alpha = np.clip(image[..., 3], 0.0, 1.0)
    out = np.empty(image.shape[:2] + (4,), dtype=np.uint8)
    out[..., :3] = np.round(srgb * 255.0 * (alpha[..., None] > 0))
    out[..., 3] = np.round(alpha * 255.0)
    return out


def orbit_cameras(camera: Camera, scene: RenderScene, frames: int):
    """``frames`` cameras turning once around the up axis through the hair's centre."""
    b = scene.hair_bounds() or scene.bounds()
    center = np.zeros(3) if b is None else 0.5 * (b[0] + b[1])
    return [camera.orbited(2.0 * math.pi * k / frames, center, scene.up_axis) for k in range(frames)]
