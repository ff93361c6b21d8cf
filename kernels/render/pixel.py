"""The preview's pixels: camera samples, front-to-back compositing of thin strands, shading.

:func:`render_kernel`: one thread per pixel, ``spp`` stratified jittered samples. A sample's ray
finds its closest hit (:func:`.tracer.hair_closest`, :func:`.tracer.geometry_closest`). Geometry
and a strand drawn at its true width are opaque: the sample ends there, as it always did. A strand
widened to the minimum pixel width (:func:`.tracer.widen_radii`) is seen with the opacity
``a`` = true / drawn radius: the sample adds its shading with weight ``T a`` (``T``: the light
still coming through, 1 at first), keeps ``T (1 - a)`` and looks for the next hit behind it.
After :data:`MAX_LAYERS` such layers, or once ``T`` < :data:`TAIL`, one last search keeps a hit with
probability its opacity (stochastic transparency) and gives it what is left of ``T``, so the
coverage stays unbiased at a bounded cost.

Writes the linear straight colour (the weighted mean radiance of what the samples saw) and alpha =
coverage (the mean of ``1 - T`` at the end of each sample), and sets ``hair_seen[0]`` to 1 where a
sample's first hit is a strand (the host warns about a camera that sees no strand).
"""

import warp as wp

from .shading import hair_bsdf
from .tracer import (HIT_NONE, RenderCamera, RenderHair, RenderLights, RenderShapes, camera_ray,
                     geometry_blocks, geometry_closest, hair_closest, hair_opacity, hair_transmittance,
                     segment_param)

#: widened strands composited front to back before the stochastic last search
MAX_LAYERS = wp.constant(2)
#: light left below which the last search is stochastic
TAIL = wp.constant(0.05)


@wp.func
def shade_geometry(shapes: RenderShapes, hair: RenderHair, lights: RenderLights, p: wp.vec3, n_geo: wp.vec3,
                   V: wp.vec3):
    """Neutral Lambertian geometry at ``p``; normals face the camera."""
    n = n_geo
    if wp.dot(n, V) < 0.0:
        n = -n
    eps = 1.0e-4 * (1.0 + wp.length(p))
    e = wp.vec3(0.0, 0.0, 0.0)  # irradiance from the two lights
    nl = wp.dot(n, lights.key_dir)
    if nl > 0.0:
        so = p + n * eps
        vis = float(1.0)
        if geometry_blocks(shapes, so, lights.key_dir):
            vis = 0.0
        else:
            vis = hair_transmittance(hair, so, lights.key_dir, -1, lights.hair_shadow_transmittance)
        e = e + lights.key_color * (nl * vis)
    nf = wp.dot(n, lights.fill_dir)
    if nf > 0.0:
        e = e + lights.fill_color * nf
    return wp.cw_mul(lights.geometry_albedo, e / 3.14159265 + lights.ambient)


@wp.func
def shade_hair(shapes: RenderShapes, hair: RenderHair, lights: RenderLights, seg: int, p: wp.vec3, V: wp.vec3):
    """Radiance of the strand segment ``seg`` at ``p`` towards ``-V``, and its opacity there."""
    v = hair.seg_v0[seg]
    a = hair.points[v]
    b = hair.points[v + 1]
    ab = b - a
    len2 = wp.dot(ab, ab)
    u = segment_param(hair, v, p)
    T = wp.vec3(1.0, 0.0, 0.0)
    if len2 > 0.0:
        T = ab / wp.sqrt(len2)
    color = hair.colors[v] * (1.0 - u) + hair.colors[v + 1] * u
    axis_p = a + u * ab
    n = p - axis_p
    nlen = wp.length(n)
    if nlen > 0.0:
        n = n / nlen
    else:
        n = V
    eps = 1.0e-4 * (1.0 + wp.length(p))
    so = p + n * eps
    vis = float(1.0)
    if geometry_blocks(shapes, so, lights.key_dir):
        vis = 0.0
    else:
        vis = hair_transmittance(hair, so, lights.key_dir, seg, lights.hair_shadow_transmittance)
    c = wp.cw_mul(lights.ambient, color)
    if vis > 0.0:
        f = hair_bsdf(lights.shading, T, V, lights.key_dir, color, lights.roughness)
        c = c + wp.cw_mul(f, lights.key_color) * vis
    c = c + wp.cw_mul(hair_bsdf(lights.shading, T, V, lights.fill_dir, color, lights.roughness), lights.fill_color)
    return c, hair_opacity(hair, v, u)


@wp.kernel(enable_backward=False, module="unique")
def render_kernel(
    cam: RenderCamera,
    hair: RenderHair,
    shapes: RenderShapes,
    lights: RenderLights,
    spp: int,
    seed: int,
    row_offset: int,
    image: wp.array2d(dtype=wp.vec4),
    hair_seen: wp.array(dtype=wp.int32),
):
    """One pixel: ``spp`` jittered samples on a stratified grid; straight colour + coverage.
    Launched over (rows, width) from image row ``row_offset`` (the CPU splits the image in
    bands rendered by several threads). A pixel with a sample whose first hit is a strand sets
    ``hair_seen[0] = 1`` (every such pixel writes the same value: a plain store, no atomic)."""
    ty, px = wp.tid()
    py = ty + row_offset
    state = wp.rand_init(seed, py * cam.width + px)
    grid = int(wp.ceil(wp.sqrt(float(spp))))
    rows = (spp + grid - 1) // grid
    radiance = wp.vec3(0.0, 0.0, 0.0)
    cover = float(0.0)
    hair_hits = int(0)
    for s in range(spp):
        jx = (float(s % grid) + wp.randf(state)) / float(grid)
        jy = (float(s // grid) + wp.randf(state)) / float(rows)
        ro, rd, t_near, t_far = camera_ray(cam, float(px) + jx, float(py) + jy)
        V = -rd
        t_lo = t_near
        skip = int(-1)
        light = float(1.0)  # what still comes through the strands composited so far
        layer = int(0)
        while light > 0.0:
            key = int(-1)
            if layer >= MAX_LAYERS or light < TAIL:
                key = wp.randi(state, 0, 2147483647)
            t_hair, seg = hair_closest(hair, ro, rd, t_lo, t_far, skip, key)
            t_geo, kind, index, n_geo = geometry_closest(shapes, ro, rd, t_lo, t_hair)
            if seg < 0 and kind == HIT_NONE:
                break
            w = light
            if kind != HIT_NONE:
                c = shade_geometry(shapes, hair, lights, ro + t_geo * rd, n_geo, V)
            else:
                if layer == 0:
                    hair_hits += 1
                c, opacity = shade_hair(shapes, hair, lights, seg, ro + t_hair * rd, V)
                if key < 0:
                    w = light * opacity
            radiance += c * w
            cover += w
            light = light - w
            if kind != HIT_NONE or key >= 0:
                break
            t_lo = t_hair
            skip = seg
            layer += 1
    if cover > 0.0:
        radiance = radiance / cover
    if hair_hits > 0:
        hair_seen[0] = 1
    image[py, px] = wp.vec4(radiance[0], radiance[1], radiance[2], cover / float(spp))
