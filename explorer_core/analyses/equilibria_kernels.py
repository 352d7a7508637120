"""The frozen field's equilibria as numba kernels: two conics intersected, the points classified, matched.

:mod:`explorer_core.analyses.equilibria` explains the algorithm (rotate, eliminate ``v`` with the
Sylvester resultant, companion eigenvalues, candidates polished by Newton) and holds the public
functions; this module is their compiled arithmetic. Lists became fixed-size arrays: a resultant of
degree <= 4 has at most 4 roots, so two conics meet in at most 4 isolated points; at most 16
candidates (4 values of ``u``, 2 conics, 2 roots ``v`` each) are polished. Every operation is done
in the same order as in the plain-Python reference (``tests/naive.py``), so the points agree to
rounding. The kernels hold no GIL (``nogil``): the app draws the tracks beside the section's
integration, and every frame of a played parameter draws them again.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numba import types

from explorer_core.system.model import coefficients_at, forcing_g

_jit = nb.njit(nogil=True, cache=True, fastmath=False, error_model="numpy")

_EPS = float(np.finfo(float).eps)
# Candidate rotations (cos, sin); odd angles so that no axis-aligned or
# diagonal conic direction (q, r, q = +-r) falls on one of them.
_ROT = np.array([(math.cos(0.377 + k * math.pi / 8), math.sin(0.377 + k * math.pi / 8)) for k in range(8)])
# A resultant coefficient smaller than this times its absolute-value bound is noise.
_NOISE = 1e4 * _EPS
# Length floor of the residual scale (units of q, r): only matters at an exact root at the origin.
_L0 = 1e-12

#: At most this many isolated intersections (Bezout).
MAX_POINTS = 4

# What a solve ended with (``info[:, 0]``); the messages are in :func:`equilibria.solve_conics`.
SOLVED = 0  # isolated points (possibly none): the others say why there are none to give
Q_ZERO = 1  # Q vanishes identically
R_ZERO = 2  # R vanishes identically
CONSTANT = 3  # one conic is a non-zero constant: no point at all
COMMON = 4  # the resultant vanishes identically: a common component
EIG_FAILED = 5  # LAPACK's eigenvalue iteration did not converge

# Type codes: the index into equilibria.TYPES.
SADDLE, STABLE_NODE, UNSTABLE_NODE, STABLE_FOCUS, UNSTABLE_FOCUS, CENTRE, DEGENERATE = range(7)

# LAPACK's dgeev through numba's own helper (what np.linalg.eigvals calls in numba): real wr, wi, so
# a complex pair needs no complex matrix (numba's eigvals refuses a real matrix with complex eigenvalues).
_rgeev = types.ExternalFunction(
    "numba_ez_rgeev",
    types.intc(
        types.char,  # kind
        types.char,  # jobvl
        types.char,  # jobvr
        types.intp,  # n
        types.CPointer(types.float64),  # a (column-major)
        types.intp,  # lda
        types.CPointer(types.float64),  # wr
        types.CPointer(types.float64),  # wi
        types.CPointer(types.float64),  # vl
        types.intp,  # ldvl
        types.CPointer(types.float64),  # vr
        types.intp,  # ldvr
    ),
)
_KIND_D = ord("d")
# Companion matrices with a larger entry are scaled (see _poly_roots); dgeev's own scaling starts at
# sqrt(safmin) / eps ~ 1.5e138.
_BIG_ENTRY = 2.0**400
_JOB_N = ord("N")


# ---------------------------------------------------------------------------
# Polynomials in u as (coefficient array, length), low -> high.


@_jit
def _pmul(p: np.ndarray, lp: int, q: np.ndarray, lq: int, out: np.ndarray) -> int:
    n = lp + lq - 1
    for i in range(n):
        out[i] = 0.0
    for i in range(lp):
        for j in range(lq):
            out[i + j] += p[i] * q[j]
    return n


@_jit
def _padd(p: np.ndarray, lp: int, q: np.ndarray, lq: int, sign: float, out: np.ndarray) -> int:
    n = max(lp, lq)
    for i in range(n):
        out[i] = p[i] if i < lp else 0.0
    for i in range(lq):
        out[i] += sign * q[i]
    return n


@_jit
def _choose_angle(cq: np.ndarray, cr: np.ndarray) -> int:
    """The candidate rotation whose smaller relative leading ``v`` coefficient (of the two conics) is largest."""
    best, choice = -1.0, 0
    for k in range(_ROT.shape[0]):
        cs, sn = _ROT[k, 0], _ROT[k, 1]
        score = math.inf
        for which in range(2):
            c = cq if which == 0 else cr
            quad = abs(c[3]) + abs(c[4]) + abs(c[5])
            if quad > 0.0:
                x = abs(c[3] * sn * sn - c[4] * cs * sn + c[5] * cs * cs) / quad
                if x < score:
                    score = x
            else:  # a line (or a constant): keep its v coefficient instead
                lin = abs(c[1]) + abs(c[2])
                if lin > 0.0:
                    x = abs(c[2] * cs - c[1] * sn) / lin
                    if x < score:
                        score = x
        if score > best:
            best, choice = score, k
    return choice


@_jit
def _in_v(c: np.ndarray, cs: float, sn: float, out: np.ndarray) -> int:
    """The conic in ``(u, v)`` (``q = cs u - sn v``, ``r = sn u + cs v``): ``out[k]`` the coefficient of ``v^k``.

    ``out[0]`` has 3 coefficients in ``u``, ``out[1]`` 2, ``out[2]`` 1. Returns the number of powers of
    ``v`` kept (3, 2 when the ``v^2`` term vanishes), 0 for a conic that is a constant.
    """
    c0, c1, c2, c3, c4, c5 = c[0], c[1], c[2], c[3], c[4], c[5]
    a2 = c3 * sn * sn - c4 * cs * sn + c5 * cs * cs
    out[1, 0] = c2 * cs - c1 * sn
    out[1, 1] = 2.0 * (c5 - c3) * cs * sn + c4 * (cs * cs - sn * sn)
    out[0, 0] = c0
    out[0, 1] = c1 * cs + c2 * sn
    out[0, 2] = c3 * cs * cs + c4 * cs * sn + c5 * sn * sn
    out[2, 0] = a2
    if a2 != 0.0:
        return 3
    if out[1, 0] != 0.0 or out[1, 1] != 0.0:
        return 2
    return 0


@_jit
def _resultant(a: np.ndarray, na: int, b: np.ndarray, nb_: int, sign: float, w: np.ndarray, out: np.ndarray) -> int:
    """Sylvester resultant in ``v`` of ``sum a[k](u) v^k`` and ``sum b[k](u) v^k`` (``na, nb_`` powers of v).

    With ``sign=+1`` and absolute values of the coefficients it is a bound on the terms
    summed in each coefficient: the scale of its rounding noise. Returns its length.
    """
    if na == 2 and nb_ == 3:
        a, b = b, a
        na, nb_ = nb_, na
    if na == 3 and nb_ == 3:
        _pmul(a[2], 1, b[0], 3, w[0])
        _pmul(a[0], 3, b[2], 1, w[1])
        lx = _padd(w[0], 3, w[1], 3, sign, w[2])  # x = a2 b0 - a0 b2
        _pmul(a[2], 1, b[1], 2, w[0])
        _pmul(a[1], 2, b[2], 1, w[1])
        ly = _padd(w[0], 2, w[1], 2, sign, w[3])  # y = a2 b1 - a1 b2
        _pmul(a[1], 2, b[0], 3, w[0])
        _pmul(a[0], 3, b[1], 2, w[1])
        lz = _padd(w[0], 4, w[1], 4, sign, w[4])  # z = a1 b0 - a0 b1
        l0 = _pmul(w[2], lx, w[2], lx, w[0])
        l1 = _pmul(w[3], ly, w[4], lz, w[1])
        return _padd(w[0], l0, w[1], l1, sign, out)  # x^2 - y z
    if na == 3:  # (2, 1): a2 b0^2 - a1 b0 b1 + a0 b1^2
        _pmul(b[0], 3, b[0], 3, w[0])
        l1 = _pmul(a[2], 1, w[0], 5, w[1])
        _pmul(b[0], 3, b[1], 2, w[2])
        l3 = _pmul(a[1], 2, w[2], 4, w[3])
        l4 = _padd(w[1], l1, w[3], l3, sign, w[4])
        _pmul(b[1], 2, b[1], 2, w[0])
        l1 = _pmul(a[0], 3, w[0], 3, w[1])
        return _padd(w[4], l4, w[1], l1, 1.0, out)
    _pmul(a[1], 2, b[0], 3, w[0])
    _pmul(a[0], 3, b[1], 2, w[1])
    return _padd(w[0], 4, w[1], 4, sign, out)


@_jit
def _quadratic(a: float, b: float, c: float, out: np.ndarray, o: int) -> None:
    """Roots of ``a x^2 + b x + c`` (``a != 0``) into ``out[o], out[o + 1]`` (re, im), without cancellation."""
    disc = b * b - 4.0 * a * c
    if disc >= 0.0:
        s = -0.5 * (b + math.copysign(math.sqrt(disc), b))
        if s == 0.0:
            out[o, 0] = out[o, 1] = out[o + 1, 0] = out[o + 1, 1] = 0.0
            return
        out[o, 0], out[o, 1] = s / a, 0.0
        out[o + 1, 0], out[o + 1, 1] = c / s, 0.0
        return
    re, im = -b / (2.0 * a), math.sqrt(-disc) / (2.0 * abs(a))
    out[o, 0], out[o, 1] = re, im
    out[o + 1, 0], out[o + 1, 1] = re, -im


@_jit
def _poly_roots(p: np.ndarray, deg: int, roots: np.ndarray, mat: np.ndarray, wr: np.ndarray, wi: np.ndarray) -> int:
    """All roots of ``sum p[k] u^k`` (``p[deg] != 0``) into ``roots`` (re, im): closed form up to degree 2,
    else the companion matrix's eigenvalues. Returns their number, -1 if LAPACK failed."""
    while True:
        if deg == 1:
            roots[0, 0], roots[0, 1] = -p[0] / p[1], 0.0
            return 1
        if deg == 2:
            _quadratic(p[2], p[1], p[0], roots, 0)
            return 2
        finite = True
        for i in range(deg):
            if not math.isfinite(-p[i] / p[deg]):
                finite = False
        if finite:
            break
        deg -= 1  # overflow: that root is at infinity for all purposes
    # A companion matrix with an entry beyond ~1.5e138 takes dgeev's own scaling path, and there scipy's
    # OpenBLAS 0.3.30 (the one numba calls) returns garbage (roots 1e-5 for roots 1e47; numpy's 0.3.31
    # does not). Below, both give the same roots bit for bit. So only then are the roots computed in
    # units of 2^e, a power of two at least the bound max_i |p_i / p_deg|^(1 / (deg - i)) on their
    # size, which puts the last column at most 1 (scaling by a power of two is exact); elsewhere the
    # matrix is left as it is: a double root's split (~sqrt(eps)) depends on the last bit.
    big = 0.0
    for i in range(deg):
        big = max(big, abs(p[i] / p[deg]))
    e = 0
    if big > _BIG_ENTRY:
        bound = 0.0
        for i in range(deg):
            if p[i] != 0.0:
                bound = max(bound, abs(p[i] / p[deg]) ** (1.0 / (deg - i)))
        e = math.frexp(bound)[1]
    # The companion matrix, column-major: ones below the diagonal, -p[:deg] / p[deg] in the last column.
    for i in range(deg * deg):
        mat[i] = 0.0
    for i in range(deg - 1):
        mat[(i + 1) + i * deg] = 1.0
    for i in range(deg):
        mat[i + (deg - 1) * deg] = math.ldexp(-p[i] / p[deg], -e * (deg - i))
    info = _rgeev(_KIND_D, _JOB_N, _JOB_N, deg, mat.ctypes, deg, wr.ctypes, wi.ctypes, wr.ctypes, 1, wi.ctypes, 1)
    if info != 0:
        return -1
    for i in range(deg):
        roots[i, 0], roots[i, 1] = math.ldexp(wr[i], e), math.ldexp(wi[i], e)
    return deg


@_jit
def _residual(cq: np.ndarray, cr: np.ndarray, q: float, r: float) -> float:
    """``max(|Q| / scale_Q, |R| / scale_R)`` with ``scale = sum_k |c_k| rho^deg_k``, ``rho = |x| + L0``."""
    rho = math.hypot(q, r) + _L0
    worst = 0.0
    for which in range(2):
        c = cq if which == 0 else cr
        f = c[0] + q * (c[1] + c[3] * q + c[4] * r) + r * (c[2] + c[5] * r)
        scale = abs(c[0]) + rho * (abs(c[1]) + abs(c[2]) + rho * (abs(c[3]) + abs(c[4]) + abs(c[5])))
        if f != 0.0:
            x = abs(f) / scale if scale > 0.0 else math.inf
            if x > worst:
                worst = x
    return worst


@_jit
def _polish(cq: np.ndarray, cr: np.ndarray, q: float, r: float) -> tuple[float, float, float]:
    """Newton on ``Q = R = 0`` with the exact Jacobian (8 steps at most); a step is kept only if it lowers
    the residual."""
    res = _residual(cq, cr, q, r)
    for _ in range(8):
        if res <= 2.0 * _EPS:
            break
        fq = cq[0] + q * (cq[1] + cq[3] * q + cq[4] * r) + r * (cq[2] + cq[5] * r)
        fr = cr[0] + q * (cr[1] + cr[3] * q + cr[4] * r) + r * (cr[2] + cr[5] * r)
        j11 = cq[1] + 2.0 * cq[3] * q + cq[4] * r
        j12 = cq[2] + cq[4] * q + 2.0 * cq[5] * r
        j21 = cr[1] + 2.0 * cr[3] * q + cr[4] * r
        j22 = cr[2] + cr[4] * q + 2.0 * cr[5] * r
        det = j11 * j22 - j12 * j21
        if det == 0.0:
            break
        q1 = q - (j22 * fq - j12 * fr) / det
        r1 = r - (j11 * fr - j21 * fq) / det
        res1 = _residual(cq, cr, q1, r1) if math.isfinite(q1) and math.isfinite(r1) else math.inf
        if not res1 < res:
            break
        q, r, res = q1, r1, res1
    return q, r, res


@_jit
def _before(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> bool:
    """``(a0, a1, a2) < (b0, b1, b2)`` as Python compares tuples."""
    if a0 != b0:
        return a0 < b0
    if a1 != b1:
        return a1 < b1
    return a2 < b2


@_jit
def _solve_one(
    cq: np.ndarray,
    cr: np.ndarray,
    inf_norm: float,
    imag_tol: float,
    accept_tol: float,
    dedupe_tol: float,
    out: np.ndarray,
    w: np.ndarray,
) -> tuple[int, int, int, int]:
    """Finite real intersections of two conics into ``out[:n]`` (q, r), sorted by ``q`` then ``r``.

    Returns ``(code, n, at_infinity, n_complex)``; ``w`` is a (27, 16) scratch array.
    """
    zq = True
    zr = True
    for i in range(6):
        zq = zq and cq[i] == 0.0
        zr = zr and cr[i] == 0.0
    if zq:
        return Q_ZERO, 0, 0, 0
    if zr:
        return R_ZERO, 0, 0, 0
    k = _choose_angle(cq, cr)
    cs, sn = _ROT[k, 0], _ROT[k, 1]
    a = w[0:3, 0:3]
    b = w[3:6, 0:3]
    na = _in_v(cq, cs, sn, a)
    nb_ = _in_v(cr, cs, sn, b)
    if na == 0 or nb_ == 0:
        return CONSTANT, 0, 4, 0  # a non-zero constant: no equilibria at all
    absa = w[6:9, 0:3]
    absb = w[9:12, 0:3]
    for i in range(3):
        for j in range(3):
            absa[i, j] = abs(a[i, j])
            absb[i, j] = abs(b[i, j])
    res = w[12]
    bound = w[13]
    lres = _resultant(a, na, b, nb_, -1.0, w[14:19], res)
    _resultant(absa, na, absb, nb_, 1.0, w[14:19], bound)
    # Coefficients at rounding-noise level are exact zeros; leading ones are intersections at infinity.
    deg = -1
    for i in range(lres):
        if abs(res[i]) > _NOISE * bound[i]:
            deg = i
    if deg < 0:
        return COMMON, 0, 0, 0
    roots = w[19:23, 0:2]  # (re, im) of each root
    nroots = 0
    if deg > 0:
        nroots = _poly_roots(res, deg, roots, w[23], w[24, 0:4], w[24, 4:8])
    if nroots < 0:
        return EIG_FAILED, 0, 0, 0
    kept = 0
    umax = 0.0
    for i in range(nroots):
        re, im = roots[i, 0], roots[i, 1]
        if math.isfinite(re) and math.isfinite(im) and math.hypot(re, im) <= inf_norm:
            roots[kept, 0], roots[kept, 1] = re, im
            kept += 1
            if math.hypot(re, im) > umax:
                umax = math.hypot(re, im)
    at_infinity = 4 - kept
    real_u = np.empty(4)
    nreal = 0
    for i in range(kept):
        if abs(roots[i, 1]) <= imag_tol * (math.hypot(roots[i, 0], roots[i, 1]) + umax):
            # insertion sort: real_u ascending
            u = roots[i, 0]
            j = nreal
            while j > 0 and real_u[j - 1] > u:
                real_u[j] = real_u[j - 1]
                j -= 1
            real_u[j] = u
            nreal += 1
    n_complex = kept - nreal
    # Clusters of (nearly) equal real roots with their multiplicity: a cluster of k
    # roots holds at most k intersections, which stops one ill-conditioned point
    # (nearly singular Jacobian, far out) from being reported twice.
    cluster = np.empty(4, np.int64)
    size = np.zeros(4, np.int64)
    nclusters = 0
    for i in range(nreal):
        u = real_u[i]
        if nclusters > 0 and u - real_u[i - 1] <= 1e-6 * abs(u) + 1e-9 * umax:
            cluster[i] = nclusters - 1
        else:
            cluster[i] = nclusters
            nclusters += 1
        size[cluster[i]] += 1
    # Every real root v of either conic at each u (two points may share u), polished.
    found = np.empty((16, 3))
    nfound = 0
    for i in range(nreal):
        u = real_u[i]
        if i > 0 and u == real_u[i - 1]:
            continue
        for which in range(2):
            p = a if which == 0 else b
            npow = na if which == 0 else nb_
            k0 = p[0, 0] + p[0, 1] * u + p[0, 2] * (u * u)
            k1 = p[1, 0] + p[1, 1] * u
            nv = 0
            v0 = v1 = 0.0
            if npow == 3 and p[2, 0] != 0.0:
                # The real parts of the roots, each once (both roots of a complex pair share theirs).
                _quadratic(p[2, 0], k1, k0, w[25:27, 0:2], 0)
                v0, v1 = w[25, 0], w[26, 0]
                nv = 1 if v0 == v1 else 2
            elif k1 != 0.0:
                v0 = -k0 / k1
                nv = 1
            for m in range(nv):
                v = v0 if m == 0 else v1
                q0, r0 = cs * u - sn * v, sn * u + cs * v
                if _residual(cq, cr, q0, r0) > 1e-3:
                    continue  # on one conic only, far from the other
                q0, r0, rs = _polish(cq, cr, q0, r0)
                if rs <= accept_tol and math.hypot(q0, r0) <= inf_norm:
                    found[nfound, 0], found[nfound, 1], found[nfound, 2] = rs, q0, r0
                    nfound += 1
    # Best residual first (then q, r: a total order).
    for i in range(1, nfound):
        x0, x1, x2 = found[i, 0], found[i, 1], found[i, 2]
        j = i
        while j > 0 and _before(x0, x1, x2, found[j - 1, 0], found[j - 1, 1], found[j - 1, 2]):
            found[j, 0], found[j, 1], found[j, 2] = found[j - 1, 0], found[j - 1, 1], found[j - 1, 2]
            j -= 1
        found[j, 0], found[j, 1], found[j, 2] = x0, x1, x2
    # Each point goes to the cluster nearest its own u (two roots can be close, and a
    # candidate from one may polish into the other's point).
    taken = np.zeros(4, np.int64)
    n = 0
    for f in range(nfound):
        q0, r0 = found[f, 1], found[f, 2]
        u0 = cs * q0 + sn * r0
        c = -1
        dbest = math.inf
        for i in range(nreal):
            d = abs(u0 - real_u[i])
            if d < dbest:  # the first (lowest) cluster of the nearest roots
                dbest, c = d, cluster[i]
        if taken[c] == size[c]:
            continue
        far = True
        for i in range(n):
            if not math.hypot(q0 - out[i, 0], r0 - out[i, 1]) > dedupe_tol * (1.0 + math.hypot(q0, r0)):
                far = False
                break
        if far:
            out[n, 0], out[n, 1] = q0, r0
            taken[c] += 1
            n += 1
    for i in range(1, n):
        x0, x1 = out[i, 0], out[i, 1]
        j = i
        while j > 0 and _before(x0, x1, 0.0, out[j - 1, 0], out[j - 1, 1], 0.0):
            out[j, 0], out[j, 1] = out[j - 1, 0], out[j - 1, 1]
            j -= 1
        out[j, 0], out[j, 1] = x0, x1
    return SOLVED, n, at_infinity, n_complex


@_jit
def solve_pairs(
    coef: np.ndarray,
    inf_norm: float,
    imag_tol: float,
    accept_tol: float,
    dedupe_tol: float,
    points: np.ndarray,
    info: np.ndarray,
) -> None:
    """Intersect the conic pairs ``coef[i] = (Q row, R row)`` (m, 2, 6): points into ``points[i, :n]``
    (m, 4, 2), ``info[i] = (code, n, at_infinity, n_complex)`` (m, 4)."""
    w = np.empty((27, 16))
    for i in range(coef.shape[0]):
        code, n, at_inf, n_cx = _solve_one(
            coef[i, 0], coef[i, 1], inf_norm, imag_tol, accept_tol, dedupe_tol, points[i], w
        )
        info[i, 0], info[i, 1], info[i, 2], info[i, 3] = code, n, at_inf, n_cx


# ---------------------------------------------------------------------------
# Classification of a point by its Jacobian.


@_jit
def _eig2(j11: float, j12: float, j21: float, j22: float) -> tuple[complex, complex]:
    """Eigenvalues of a real 2x2 matrix, larger real part first, ``+im`` first in a pair."""
    half = 0.5 * (j11 + j22)
    det = j11 * j22 - j12 * j21
    # (j11 - j22)^2 / 4 + j12 j21 is the discriminant without the cancellation of half^2 - det.
    disc = 0.25 * (j11 - j22) ** 2 + j12 * j21
    if disc >= 0.0:
        s = math.sqrt(disc)
        big = half + math.copysign(s, half) if half != 0.0 else s
        small = det / big if big != 0.0 else half - s
        if big >= small:
            return complex(big, 0.0), complex(small, 0.0)
        return complex(small, 0.0), complex(big, 0.0)
    s = math.sqrt(-disc)
    return complex(half, s), complex(half, -s)


@_jit
def _type(j11: float, j12: float, j21: float, j22: float, rtol: float) -> int:
    """The type code (index into ``equilibria.TYPES``), see :func:`equilibria.classify`."""
    tr = j11 + j22
    det = j11 * j22 - j12 * j21
    n2 = j11 * j11 + j12 * j12 + j21 * j21 + j22 * j22
    if abs(det) <= rtol * n2:
        return DEGENERATE
    if det < 0.0:
        return SADDLE
    if abs(tr) <= rtol * math.sqrt(n2):
        return CENTRE
    if tr * tr >= 4.0 * det:
        return STABLE_NODE if tr < 0.0 else UNSTABLE_NODE
    return STABLE_FOCUS if tr < 0.0 else UNSTABLE_FOCUS


@_jit
def classify_stack(jac: np.ndarray, rtol: float, eig: np.ndarray, kinds: np.ndarray) -> None:
    """Eigenvalues ``eig[i]`` (n, 2) and type code ``kinds[i]`` of each 2x2 matrix ``jac[i]`` (n, 2, 2)."""
    for i in range(jac.shape[0]):
        j11, j12, j21, j22 = jac[i, 0, 0], jac[i, 0, 1], jac[i, 1, 0], jac[i, 1, 1]
        eig[i, 0], eig[i, 1] = _eig2(j11, j12, j21, j22)
        kinds[i] = _type(j11, j12, j21, j22, rtol)


# ---------------------------------------------------------------------------
# Equilibria at many frozen times.


@_jit
def equilibria_at(
    num: np.ndarray,
    gpc: np.ndarray,
    den: np.ndarray,
    forcing: np.ndarray,
    ts: np.ndarray,
    o: int,
    inf_norm: float,
    rtol: float,
    points: np.ndarray,
    info: np.ndarray,
    eig: np.ndarray,
    kinds: np.ndarray,
) -> None:
    """The equilibria of one model's frozen field at each time ``ts[i]``, into row ``o + i`` of the outputs.

    ``points`` (., 4, 2), ``info`` (., 4) as :func:`solve_pairs`
    (default tolerances); ``eig`` (., 4, 2) complex and ``kinds`` (., 4) of each point, from the exact
    Jacobian of the same coefficients the roots were computed from.
    """
    w = np.empty((27, 16))
    c = np.empty((2, 6))  # the conics Q, R at one time
    for i in range(ts.shape[0]):
        row = o + i
        g, gp = forcing_g(forcing, ts[i])
        coefficients_at(num, gpc, den, g, gp, c)
        cq, cr = c[0], c[1]
        code, n, at_inf, n_cx = _solve_one(cq, cr, inf_norm, 1e-5, 1e-9, 1e-7, points[row], w)
        info[row, 0], info[row, 1], info[row, 2], info[row, 3] = code, n, at_inf, n_cx
        for k in range(n):
            q, r = points[row, k, 0], points[row, k, 1]
            j11 = cq[1] + 2.0 * cq[3] * q + cq[4] * r
            j12 = cq[2] + cq[4] * q + 2.0 * cq[5] * r
            j21 = cr[1] + 2.0 * cr[3] * q + cr[4] * r
            j22 = cr[2] + cr[4] * q + 2.0 * cr[5] * r
            eig[row, k, 0], eig[row, k, 1] = _eig2(j11, j12, j21, j22)
            kinds[row, k] = _type(j11, j12, j21, j22, rtol)


# ---------------------------------------------------------------------------
# The tracks: matching the points of two frozen times, numbering the branches.


@_jit
def _match(points: np.ndarray, info: np.ndarray, sa: int, sb: int, jump: float, pairs: np.ndarray) -> tuple[int, bool]:
    """Nearest assignment of the points of sample ``sa`` to those of ``sb`` (see ``equilibria._match``).

    ``pairs[:npairs]`` the pairs ``(i, j)`` within ``jump``; returns ``(npairs, clear)``. Every
    assignment is tried in ``itertools.permutations`` order and the first of least total
    ``min(distance, jump)`` kept, as the Python reference does.
    """
    na, nb_ = info[sa, 1], info[sb, 1]
    if na == 0 or nb_ == 0:
        return 0, na == nb_
    ca = np.empty((4, 2))
    cb = np.empty((4, 2))
    for i in range(na):
        s = 1.0 / (1.0 + math.hypot(points[sa, i, 0], points[sa, i, 1]))
        ca[i, 0], ca[i, 1] = points[sa, i, 0] * s, points[sa, i, 1] * s
    for j in range(nb_):
        s = 1.0 / (1.0 + math.hypot(points[sb, j, 0], points[sb, j, 1]))
        cb[j, 0], cb[j, 1] = points[sb, j, 0] * s, points[sb, j, 1] * s
    d = np.empty((4, 4))
    for i in range(na):
        for j in range(nb_):
            d[i, j] = math.hypot(ca[i, 0] - cb[j, 0], ca[i, 1] - cb[j, 1])
    # The shorter side is assigned into the longer one: perm[k] for k < short, from range(long).
    flip = na > nb_
    short, long_ = (nb_, na) if flip else (na, nb_)
    perm = np.zeros(4, np.int64)
    best = np.zeros(4, np.int64)
    best_cost = math.inf
    found = False
    # All long_^short tuples in lexicographic order; the injective ones are the permutations, in order.
    for code in range(long_**short):
        x = code
        for k in range(short - 1, -1, -1):
            perm[k] = x % long_
            x //= long_
        injective = True
        for k in range(short):
            for m in range(k):
                if perm[k] == perm[m]:
                    injective = False
        if not injective:
            continue
        cost = 0.0
        for k in range(short):
            dk = d[perm[k], k] if flip else d[k, perm[k]]
            cost += jump if jump < dk else dk
        if not found or cost < best_cost:
            found = True
            best_cost = cost
            best[:short] = perm[:short]
    npairs = 0
    clear = na == nb_
    for k in range(short):
        i, j = (best[k], k) if flip else (k, best[k])
        dij = d[i, j]
        if dij <= jump:
            pairs[npairs, 0], pairs[npairs, 1] = i, j
            npairs += 1
        else:
            clear = False
        nearest = math.inf
        for m in range(nb_):
            if m != j and d[i, m] < nearest:
                nearest = d[i, m]
        for m in range(na):
            if m != i and d[m, j] < nearest:
                nearest = d[m, j]
        if nearest < math.inf and dij > 0.5 * nearest:
            clear = False
    return npairs, clear


@_jit
def match(points: np.ndarray, info: np.ndarray, sa: int, sb: int, jump: float, pairs: np.ndarray) -> tuple[int, bool]:
    """:func:`_match` of two samples."""
    return _match(points, info, sa, sb, jump, pairs)


@_jit
def match_chain(
    points: np.ndarray, info: np.ndarray, n: int, jump: float, pairs: np.ndarray, npairs: np.ndarray, clear: np.ndarray
) -> None:
    """:func:`_match` of samples ``k`` and ``k + 1`` for ``k < n - 1``: ``pairs[k]`` (., 4, 2), ``npairs[k]``,
    ``clear[k]``."""
    for k in range(n - 1):
        npairs[k], clear[k] = _match(points, info, k, k + 1, jump, pairs[k])


@_jit
def number_branches(order: np.ndarray, info: np.ndarray, link: np.ndarray, branch: np.ndarray) -> int:
    """Branch ids by first appearance: ``branch[s, i]`` for point ``i`` of row ``s``, rows visited in time
    ``order``; ``link[s, i] = (s', j)`` continues point ``i`` of ``s`` as point ``j`` of ``s'`` (-1: none).
    Returns the number of branches."""
    pending = np.full(branch.shape, -1, np.int64)  # the id a link gave a point not yet visited
    n = 0
    for s in order:
        for i in range(info[s, 1]):
            b = pending[s, i]
            if b < 0:
                b = n
                n += 1
            branch[s, i] = b
            if link[s, i, 0] >= 0:
                pending[link[s, i, 0], link[s, i, 1]] = b
    return n
