"""Small-block algebra of the elastic step's banded KKT solve (kernels/solvers/elastic.py).

The solve eliminates one particle at a time; its diagonal blocks are 4x4 KKT blocks
``D = [[G, e], [e^T, 0]]`` (G the symmetric 3x3 velocity block, e the unit constraint row of the
particle's segment), stored inverted and packed symmetric (10 scalars), and its couplings
``B_{k-1,k}`` are 3x4 (the last row is zero). Functions here are specialised on the computation's
precision ``real`` (:func:`block_funcs`).

``KKT_INVERSE`` picks how ``D^-1`` is formed:

- ``"generic"``: Warp's 4x4 inverse of D symmetrised, ``(G + G^T) / 2`` (its cofactors);
- ``"plane"``: in the plane normal to e, with ``N`` (3x2) an orthonormal basis of it and
  ``H = N^T G N``: ``D^-1 = [[N H^-1 N^T, m], [m^T, -e^T G m]]``, ``m = e - N H^-1 N^T G e``
  (from ``v = N y + c e``), formed from G's upper triangle only (symmetric by construction), in the
  computation's precision, with no cancellation of large terms.
"""

import functools
import types

import warp as wp

#: how the KKT block is inverted: "generic" or "plane" (module docstring)
KKT_INVERSE = "generic"


@functools.cache
def block_funcs(real):
    """The block functions for the computation's precision ``real`` (a namespace of ``wp.func``)."""
    vec3 = wp.types.vector(3, real)
    mat33 = wp.types.matrix((3, 3), real)
    mat44 = wp.types.matrix((4, 4), real)
    mat34 = wp.types.matrix((3, 4), real)
    vec6 = wp.types.vector(6, real)
    vec10 = wp.types.vector(10, real)

    quat = wp.types.quaternion(real)

    @wp.func
    def between(a: vec3, b: vec3):
        """Minimal rotation taking unit ``a`` to the direction of ``b`` (the root frame's, in the step
        and in the energy check)."""
        bn = wp.normalize(b)
        c = wp.cross(a, bn)
        w = real(1.0) + wp.dot(a, bn)
        if w < real(1.0e-12):
            ref = vec3(real(0.0), real(1.0), real(0.0))
            if wp.abs(a[0]) < real(0.9):
                ref = vec3(real(1.0), real(0.0), real(0.0))
            c = wp.cross(a, ref)
            w = real(0.0)
        return wp.quat_to_matrix(wp.normalize(quat(c[0], c[1], c[2], w)))

    @wp.func
    def curv(xm: vec3, x: vec3, xp: vec3, lj: real, lj1: real):
        """(Dx)_j from x_{j-1}, x_j, x_{j+1} and the segment lengths l_j, l_{j+1}."""
        al = real(1.0) / lj
        ga = real(1.0) / lj1
        return -(al * (x - xm)) + ga * (xp - x)

    @wp.func
    def pack_symmetric(D: mat44):
        """The 10 entries of a symmetric 4x4 matrix on and above its diagonal."""
        return vec10(D[0, 0], D[0, 1], D[0, 2], D[0, 3], D[1, 1], D[1, 2], D[1, 3], D[2, 2], D[2, 3], D[3, 3])

    @wp.func
    def unpack_symmetric(p: vec10):
        return mat44(p[0], p[1], p[2], p[3],
                     p[1], p[4], p[5], p[6],
                     p[2], p[5], p[7], p[8],
                     p[3], p[6], p[8], p[9])

    @wp.func
    def upper3_packed(p: vec10):
        """The 6 entries on and above the diagonal of the upper 3x3 (velocity part) of a packed
        symmetric 4x4 matrix."""
        return vec6(p[0], p[1], p[2], p[4], p[5], p[7])

    @wp.func
    def unpack_symmetric3(q: vec6):
        return mat33(q[0], q[1], q[2],
                     q[1], q[3], q[4],
                     q[2], q[4], q[5])

    @wp.func
    def block0(G: mat33, e: vec3):
        """The diagonal block with velocity part G and constraint row e."""
        return mat44(G[0, 0], G[0, 1], G[0, 2], e[0],
                     G[1, 0], G[1, 1], G[1, 2], e[1],
                     G[2, 0], G[2, 1], G[2, 2], e[2],
                     e[0], e[1], e[2], real(0.0))

    @wp.func
    def block1(a1: real, e: vec3, a2: real, BD: mat34):
        """B_{k-1,k} = A_{k-1,k} - a2 P D_{k+1}^-1 B_{k,k+1}^T, rows 0-2 (its last row is zero), from
        BD = B_{k,k+1} D_{k+1}^-1: P D^-1 B^T P is the transpose of BD's left 3x3 (D^-1 symmetric)."""
        z = real(0.0)
        return mat34(a1 - a2 * BD[0, 0], z - a2 * BD[1, 0], z - a2 * BD[2, 0], -e[0],
                     z - a2 * BD[0, 1], a1 - a2 * BD[1, 1], z - a2 * BD[2, 1], -e[1],
                     z - a2 * BD[0, 2], z - a2 * BD[1, 2], a1 - a2 * BD[2, 2], -e[2])

    @wp.func
    def kkt_generic(a0: real, BD: mat34, Bk1: mat34, a22: real, Di2u: vec6, e: vec3):
        """D_k^-1 packed, D_k's velocity block ``a0 I - BD Bk1^T - a22 (D_{k+2}^-1)_vv``: Warp's 4x4
        inverse of D_k symmetrised (D_k is symmetric but for the products' rounding; inverted as it
        was, a styled groom at rest drifted 3e-9 L instead of < 1e-10 in float64)."""
        z = real(0.0)
        G = mat33(a0, z, z, z, a0, z, z, z, a0) - BD * wp.transpose(Bk1) - a22 * unpack_symmetric3(Di2u)
        return pack_symmetric(wp.inverse(block0(real(0.5) * (G + wp.transpose(G)), e)))

    @wp.func
    def kkt_plane(a0: real, BD: mat34, Bk1: mat34, a22: real, Di2u: vec6, e: vec3):
        """D_k^-1 packed, as :func:`kkt_generic`, in the plane normal to e (module docstring); for
        |e| != 1 (rounding of the lengths) the last row and column scale by 1/|e|, the corner by
        1/|e|^2."""
        r0 = BD[0]
        r1 = BD[1]
        r2 = BD[2]
        b0 = Bk1[0]
        b1 = Bk1[1]
        b2 = Bk1[2]
        g00 = a0 - wp.dot(r0, b0) - a22 * Di2u[0]
        g01 = -wp.dot(r0, b1) - a22 * Di2u[1]
        g02 = -wp.dot(r0, b2) - a22 * Di2u[2]
        g11 = a0 - wp.dot(r1, b1) - a22 * Di2u[3]
        g12 = -wp.dot(r1, b2) - a22 * Di2u[4]
        g22 = a0 - wp.dot(r2, b2) - a22 * Di2u[5]
        G = mat33(g00, g01, g02, g01, g11, g12, g02, g12, g22)
        il = real(1.0) / wp.length(e)
        u = e * il
        # a branch-free orthonormal basis of the plane normal to u (Duff et al. 2017)
        sg = real(1.0)
        if u[2] < real(0.0):
            sg = real(-1.0)
        ia = real(-1.0) / (sg + u[2])
        bb = u[0] * u[1] * ia
        n1 = vec3(real(1.0) + sg * u[0] * u[0] * ia, sg * bb, -sg * u[0])
        n2 = vec3(bb, sg + u[1] * u[1] * ia, -u[1])
        g1 = G * n1
        g2 = G * n2
        gu = G * u
        h11 = wp.dot(n1, g1)
        h12 = wp.dot(n1, g2)
        h22 = wp.dot(n2, g2)
        idet = real(1.0) / (h11 * h22 - h12 * h12)
        i11 = h22 * idet
        i12 = -h12 * idet
        i22 = h11 * idet
        # N H^-1 N^T = a1 n1^T + a2 n2^T with a1 = N H^-1 (1, 0), a2 = N H^-1 (0, 1)
        a1 = i11 * n1 + i12 * n2
        a2 = i12 * n1 + i22 * n2
        m = u - (wp.dot(n1, gu) * a1 + wp.dot(n2, gu) * a2)
        corner = -wp.dot(gu, m) * il * il
        m = m * il
        return vec10(a1[0] * n1[0] + a2[0] * n2[0], a1[0] * n1[1] + a2[0] * n2[1], a1[0] * n1[2] + a2[0] * n2[2], m[0],
                     a1[1] * n1[1] + a2[1] * n2[1], a1[1] * n1[2] + a2[1] * n2[2], m[1],
                     a1[2] * n1[2] + a2[2] * n2[2], m[2], corner)

    return types.SimpleNamespace(between=between, curv=curv, unpack_symmetric=unpack_symmetric, upper3_packed=upper3_packed,
                                 block1=block1, kkt_generic=kkt_generic, kkt_plane=kkt_plane)
