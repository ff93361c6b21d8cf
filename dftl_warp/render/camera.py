"""The camera model of UsdGeom.Camera, its conforming to an image, automatic framing, orbits.

Conventions (as USD): the camera looks down its local -Z with +Y up; focal length and
apertures are in tenths of a stage unit (millimetres for a metre stage), so only their ratios
matter for a perspective camera; an orthographic camera's aperture is its window size in
tenths of a stage unit. ``world_from_camera`` is a 4x4 matrix for column vectors
(``p_world = M @ [p, 1]``), i.e. the transpose of USD's row-vector matrix.

When the image aspect (width / height) differs from the aperture aspect, the window is
conformed as the UsdRender ``aspectRatioConformPolicy`` says (default ``expandAperture``: the
whole authored aperture stays visible and the other direction grows).

A :class:`Camera` is checked when it is built (and again by the renderer, which sees fields set
later): a 4x4 matrix of finite numbers, a finite focal length and apertures > 0, finite aperture
offsets, 0 <= near < far, a projection the renderer draws. A bad value raises
:class:`~dftl_warp.options.OptionError` (a ValueError) naming the field and the value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..options import OptionError
from ..usd.values import number, shown

#: UsdRender.Settings aspectRatioConformPolicy values this renderer honours
CONFORM_POLICIES = ("expandAperture", "cropAperture", "adjustApertureWidth", "adjustApertureHeight")

#: tenths of a stage unit: the unit of focal length and aperture
APERTURE_UNIT = 0.1

#: the projections of UsdGeom.Camera (anything else was drawn as a perspective one)
PROJECTIONS = ("perspective", "orthographic")
#: the stage up axes: framing and turntables turn about Y or Z
UP_AXES = ("Y", "Z")


def checked_up_axis(up_axis) -> str:
    """``up_axis`` ("Y" or "Z", either case) in capitals; OptionError (a ValueError, one line for
    ``dftl-warp render``) naming anything else ("W" was framed and orbited as if it were "Y")."""
    if not isinstance(up_axis, str) or up_axis.upper() not in UP_AXES:
        raise OptionError(f"up_axis {up_axis!r}: must be 'Y' or 'Z'")
    return up_axis.upper()


def _number(where: str, name: str, value) -> float:
    """``value`` as a float; OptionError naming ``name`` for a string, a bool, an array or NaN."""
    value = number(value, f"{where}{name}", error=OptionError)
    if math.isnan(value):
        raise OptionError(f"{where}{name} = nan: not a number")
    return value


def checked_matrix(value, name: str, error: type = OptionError) -> np.ndarray:
    """``value`` as a 4x4 float64 matrix; ``error`` (default OptionError) naming ``name`` (e.g.
    ``camera world_from_camera``, ``shapes[0] world_from_local``) for a value that is not a 4x4
    matrix of numbers, or naming its first entry that is not finite (a camera's drew a blank image,
    a shape's blanked the whole image)."""
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        m = None
    if m is None or m.shape != (4, 4):
        what = shown(value) if m is None else f"of shape {m.shape}"
        raise error(f"{name} {what}: expected a 4x4 matrix of numbers")
    bad = np.argwhere(~np.isfinite(m))
    if len(bad):
        i, j = (int(k) for k in bad[0])
        raise error(f"{name}[{i}][{j}] = {m[i, j]:g}: not finite")
    return m


@dataclass
class Camera:
    """A UsdGeom.Camera's parameters at one time (see module docstring for units)."""

    world_from_camera: np.ndarray
    focal_length: float = 50.0
    horizontal_aperture: float = 20.955
    vertical_aperture: float = 15.2908
    horizontal_aperture_offset: float = 0.0
    vertical_aperture_offset: float = 0.0
    near: float = 1.0
    far: float = 1.0e6
    projection: str = "perspective"
    path: str = ""

    def __post_init__(self):
        self.check()

    def check(self) -> None:
        """OptionError (a ValueError) naming the first bad field: ``world_from_camera`` not a 4x4
        matrix of finite numbers, a focal length or aperture not finite and > 0, an aperture offset
        not finite, not 0 <= near < far (far may be infinite), an unknown projection. (Such
        cameras drew a blank or NaN image, or a perspective one, without a word.)"""
        where = f"camera {self.path}: " if self.path else "camera "
        checked_matrix(self.world_from_camera, f"{where}world_from_camera")
        for name in ("focal_length", "horizontal_aperture", "vertical_aperture"):
            value = _number(where, name, getattr(self, name))
            if not math.isfinite(value):
                raise OptionError(f"{where}{name} = {value:g}: must be finite")
            if value <= 0:
                raise OptionError(f"{where}{name} = {value:g}: must be > 0")
        for name in ("horizontal_aperture_offset", "vertical_aperture_offset"):
            value = _number(where, name, getattr(self, name))
            if not math.isfinite(value):
                raise OptionError(f"{where}{name} = {value:g}: must be finite")
        near, far = _number(where, "near", self.near), _number(where, "far", self.far)
        if not (math.isfinite(near) and near >= 0):
            raise OptionError(f"{where}near = {near:g}: must be finite and >= 0")
        if not far > near:
            raise OptionError(f"{where}near = {near:g}, far = {far:g}: must have near < far")
        if not isinstance(self.projection, str) or self.projection not in PROJECTIONS:
            raise OptionError(f"{where}projection {self.projection!r}: must be 'perspective' or 'orthographic'")

    def aperture_window(self):
        """(left, right, bottom, top) of the authored aperture, in aperture units."""
        h, v = self.horizontal_aperture, self.vertical_aperture
        ho, vo = self.horizontal_aperture_offset, self.vertical_aperture_offset
        return (ho - 0.5 * h, ho + 0.5 * h, vo - 0.5 * v, vo + 0.5 * v)

    def conformed_window(self, width: int, height: int, policy: str = "expandAperture"):
        """The aperture window conformed about its centre to the image aspect ``width/height``."""
        left, right, bottom, top = self.aperture_window()
        cx, cy = 0.5 * (left + right), 0.5 * (bottom + top)
        w, h = right - left, top - bottom
        image_aspect = width / height
        aperture_aspect = w / h
        if policy not in CONFORM_POLICIES:
            raise ValueError(f"unknown conform policy {policy!r}; choose one of {CONFORM_POLICIES}")
        if policy == "expandAperture":
            policy = "adjustApertureWidth" if image_aspect > aperture_aspect else "adjustApertureHeight"
        elif policy == "cropAperture":
            policy = "adjustApertureHeight" if image_aspect > aperture_aspect else "adjustApertureWidth"
        if policy == "adjustApertureWidth":
            w = h * image_aspect
        else:
            h = w / image_aspect
        return (cx - 0.5 * w, cx + 0.5 * w, cy - 0.5 * h, cy + 0.5 * h)

    def screen_window(self, width: int, height: int, policy: str = "expandAperture"):
        """The conformed window on the plane z = -1 (perspective: film / focal length) or in
        stage units at z = 0 (orthographic)."""
        win = np.asarray(self.conformed_window(width, height, policy), dtype=np.float64)
        if self.projection == "orthographic":
            return win * APERTURE_UNIT
        return win / self.focal_length

    @property
    def position(self) -> np.ndarray:
        return np.asarray(self.world_from_camera, dtype=np.float64)[:3, 3].copy()

    def orbited(self, angle: float, center, up_axis: str = "Y") -> "Camera":
        """This camera turned by ``angle`` (radians) about the stage's up axis through ``center``."""
        rot = rotation_about_up(angle, up_axis)
        c = np.asarray(center, dtype=np.float64)
        m = np.eye(4)
        m[:3, :3] = rot
        m[:3, 3] = c - rot @ c
        return replace(self, world_from_camera=m @ np.asarray(self.world_from_camera, dtype=np.float64))

    def world_to_pixel(self, points, width: int, height: int, policy: str = "expandAperture"):
        """Pixel coordinates (x right, y down, from the image's top-left corner) and camera
        depth of world ``points`` (N, 3)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        cam = np.linalg.inv(np.asarray(self.world_from_camera, dtype=np.float64))
        q = p @ cam[:3, :3].T + cam[:3, 3]
        depth = -q[:, 2]
        left, right, bottom, top = self.screen_window(width, height, policy)
        if self.projection == "orthographic":
            sx, sy = q[:, 0], q[:, 1]
        else:
            sx, sy = q[:, 0] / depth, q[:, 1] / depth
        x = (sx - left) / (right - left) * width
        y = (top - sy) / (top - bottom) * height
        return np.stack([x, y], axis=1), depth


def rotation_about_up(angle: float, up_axis: str = "Y") -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    if checked_up_axis(up_axis) == "Z":
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def look_at(eye, target, up) -> np.ndarray:
    """world_from_camera of a camera at ``eye`` looking at ``target`` (column vectors)."""
    eye = np.asarray(eye, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(up, dtype=np.float64))
    if np.linalg.norm(right) < 1e-9:
        right = np.cross(forward, np.array([1.0, 0.0, 0.0]))
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, -forward, eye
    return m


def auto_frame(bounds, width: int, height: int, up_axis: str = "Y",
               azimuth_deg: float = 25.0, elevation_deg: float = 12.0,
               focal_length: float = 50.0) -> Camera:
    """A 35 mm-style camera (36 x 24 aperture, conformed to the image) that sees the whole
    bounding sphere of ``bounds`` = (lo, hi) from the front, slightly from the side and above.
    Without bounds, a camera at 1 unit looking at the origin."""
    if bounds is None:
        lo, hi = -np.full(3, 0.5), np.full(3, 0.5)
    else:
        lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
    up_axis = checked_up_axis(up_axis)
    center = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
    up = np.array([0.0, 0.0, 1.0]) if up_axis == "Z" else np.array([0.0, 1.0, 0.0])
    front = np.array([0.0, -1.0, 0.0]) if up_axis == "Z" else np.array([0.0, 0.0, 1.0])
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    view = rotation_about_up(az, up_axis) @ front
    view = math.cos(el) * view + math.sin(el) * up
    cam = Camera(world_from_camera=np.eye(4), focal_length=focal_length,
                 horizontal_aperture=36.0, vertical_aperture=24.0, path="<auto>")
    left, right, bottom, top = cam.screen_window(width, height)
    tan_w, tan_h = 0.5 * (right - left), 0.5 * (top - bottom)
    # the closest distance from which all 8 corners of the box are inside the window
    m = look_at(center + view, center, up)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]) - center
    cx, cy, cz = corners @ m[:3, 0], corners @ m[:3, 1], corners @ m[:3, 2]
    distance = float(np.max(np.maximum(cz + np.abs(cx) / tan_w, cz + np.abs(cy) / tan_h))) * 1.08
    distance = max(distance, 2.0 * radius * 1e-3)
    cam.world_from_camera = look_at(center + view * distance, center, up)
    cam.near = max(distance - 1.5 * radius, distance * 1e-3)
    cam.far = distance + 1.5 * radius
    # keep the 36 x 24 aperture's aspect equal to the image's: nothing to conform
    cam.horizontal_aperture = (right - left) * focal_length
    cam.vertical_aperture = (top - bottom) * focal_length
    return cam
