"""Hair shading of the preview tracer (:mod:`.tracer`): the R, TT and TRT lobes of Marschner et al.
2003 in the practical form of Karis 2016 ("Physically Based Hair Shading in Unreal"), plus a diffuse
term for multiple scattering; or Kajiya-Kay 1989. Reflected radiance per unit irradiance."""

import warp as wp

SHADING_MARSCHNER = wp.constant(0)
SHADING_KAJIYA_KAY = wp.constant(1)


@wp.func
def gauss(width: float, x: float):
    """Normalised Gaussian of standard deviation ``width`` at ``x``."""
    return wp.exp(-0.5 * x * x / (width * width)) / (2.5066283 * width)


@wp.func
def fresnel_hair(cos_theta: float):
    """Schlick Fresnel of a hair cuticle (index of refraction 1.55)."""
    f0 = 0.04652  # ((1 - 1.55) / (1 + 1.55))^2
    x = 1.0 - wp.clamp(cos_theta, 0.0, 1.0)
    x2 = x * x
    return f0 + (1.0 - f0) * x2 * x2 * x


@wp.func
def pow3(c: wp.vec3, e: float):
    return wp.vec3(wp.pow(c[0], e), wp.pow(c[1], e), wp.pow(c[2], e))


@wp.func
def hair_marschner(T: wp.vec3, V: wp.vec3, L: wp.vec3, color: wp.vec3, roughness: float):
    """Reflected radiance per unit irradiance of a fibre with tangent ``T``: R, TT and TRT lobes
    (Karis 2016 form of Marschner et al. 2003) plus a Kajiya-Kay-like multiple-scattering
    diffuse term. ``color`` is the fibre colour (0..1, linear), ``roughness`` its longitudinal
    roughness."""
    n_ior = 1.55
    shift = 0.035
    r = wp.clamp(roughness, 0.02, 1.0)
    r2 = r * r
    vol = wp.dot(V, L)
    sin_l = wp.clamp(wp.dot(T, L), -1.0, 1.0)
    sin_v = wp.clamp(wp.dot(T, V), -1.0, 1.0)
    cos_d = wp.cos(0.5 * wp.abs(wp.asin(sin_v) - wp.asin(sin_l)))
    cos_d = wp.max(cos_d, 0.05)
    lp = L - sin_l * T
    vp = V - sin_v * T
    cos_phi = wp.dot(lp, vp) / wp.sqrt(wp.dot(lp, lp) * wp.dot(vp, vp) + 1.0e-4)
    cos_half_phi = wp.sqrt(wp.clamp(0.5 + 0.5 * cos_phi, 0.0, 1.0))
    s = wp.vec3(0.0, 0.0, 0.0)
    # R: white, shifted towards the root
    mp = gauss(r2 * wp.sqrt(2.0) * wp.max(cos_half_phi, 0.05), sin_l + sin_v + 2.0 * shift)
    np_ = 0.25 * cos_half_phi
    fp = fresnel_hair(wp.sqrt(wp.clamp(0.5 + 0.5 * vol, 0.0, 1.0)))
    s = s + wp.vec3(mp * np_ * fp)
    # TT: through the fibre, tinted, strong when back-lit
    mp = gauss(0.5 * r2, sin_l + sin_v - shift)
    a = 1.0 / n_ior
    h = cos_half_phi * (1.0 + a * (0.6 - 0.8 * cos_phi))
    f = fresnel_hair(cos_d * wp.sqrt(wp.clamp(1.0 - h * h, 0.0, 1.0)))
    fp = (1.0 - f) * (1.0 - f)
    tp = pow3(color, 0.5 * wp.sqrt(wp.clamp(1.0 - (h * a) * (h * a), 0.0, 1.0)) / cos_d)
    np_ = wp.exp(-3.65 * cos_phi - 3.98)
    s = s + tp * (mp * np_ * fp)
    # TRT: the tinted secondary highlight
    mp = gauss(2.0 * r2, sin_l + sin_v - 4.0 * shift)
    f = fresnel_hair(cos_d * 0.5)
    fp = (1.0 - f) * (1.0 - f) * f
    tp = pow3(color, 0.8 / cos_d)
    np_ = wp.exp(17.0 * cos_phi - 16.78)
    s = s + tp * (mp * np_ * fp)
    # multiple scattering: a wrapped Kajiya-Kay diffuse
    kk = wp.sqrt(wp.clamp(1.0 - sin_l * sin_l, 0.0, 1.0))
    wrap = wp.clamp(0.5 + 0.5 * wp.dot(V, L), 0.0, 1.0)
    diffuse = color * (kk * (0.6 + 0.4 * wrap) / 3.14159265)
    return s + diffuse


@wp.func
def hair_kajiya_kay(T: wp.vec3, V: wp.vec3, L: wp.vec3, color: wp.vec3, roughness: float):
    """Kajiya-Kay 1989: diffuse ``sin(T, L)`` and a specular cone around the tangent."""
    sin_l2 = 1.0 - wp.dot(T, L) * wp.dot(T, L)
    sin_v2 = 1.0 - wp.dot(T, V) * wp.dot(T, V)
    tl = wp.dot(T, L)
    tv = wp.dot(T, V)
    cos_spec = wp.clamp(-tl * tv + wp.sqrt(wp.max(sin_l2, 0.0) * wp.max(sin_v2, 0.0)), 0.0, 1.0)
    exponent = 2.0 / wp.max(roughness * roughness, 1.0e-3)
    spec = 0.08 * wp.pow(cos_spec, exponent)
    return color * (wp.sqrt(wp.max(sin_l2, 0.0)) / 3.14159265) + wp.vec3(spec)


@wp.func
def hair_bsdf(shading: int, T: wp.vec3, V: wp.vec3, L: wp.vec3, color: wp.vec3, roughness: float):
    if shading == SHADING_KAJIYA_KAY:
        return hair_kajiya_kay(T, V, L, color, roughness)
    return hair_marschner(T, V, L, color, roughness)
