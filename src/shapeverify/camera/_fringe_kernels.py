"""numba kernels of the single-image fringe analysis (private to camera.fringe_analysis)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def lit_between(f, r, thr, along_rows, out):
    """True where a pixel brighter than ``thr`` lies within ``r`` pixels on BOTH sides along the
    carrier axis (u when ``along_rows``, else v); a side cut by the image border counts as bright.

    A dark fringe between two bright ones passes; a dark pixel just outside a lit area does not.
    """
    H, W = f.shape
    for i in range(H):
        for j in range(W):
            left = False
            right = False
            if along_rows:
                if j - r < 0:
                    left = True
                if j + r >= W:
                    right = True
                for k in range(max(0, j - r), j + 1):
                    if f[i, k] >= thr:
                        left = True
                        break
                for k in range(j, min(W, j + r + 1)):
                    if f[i, k] >= thr:
                        right = True
                        break
            else:
                if i - r < 0:
                    left = True
                if i + r >= H:
                    right = True
                for k in range(max(0, i - r), i + 1):
                    if f[k, j] >= thr:
                        left = True
                        break
                for k in range(i, min(H, i + r + 1)):
                    if f[k, j] >= thr:
                        right = True
                        break
            out[i, j] = left and right


@njit(cache=True, nogil=True, fastmath=True)
def demodulate(f, m, mean, col_re, col_im, row_re, row_im, g, xg, re, im, a, m0, mx, my):
    """Carrier demodulation and masked Gaussian low-pass in one separable pass.

    z = (f - mean) m exp(-2 pi i c.x) is filtered with the Gaussian ``g`` (taps, odd length, zero
    outside the image): re + i im; a = G*(f m); m0 = G*m; mx, my = first moments (x g) of the mask
    along u and v (the centroid offset of the valid part of the window is (mx, my) / m0).
    """
    H, W = f.shape
    R = g.shape[0] // 2
    dt = re.dtype
    hre = np.empty((H, W), dt)
    him = np.empty((H, W), dt)
    ha = np.empty((H, W), dt)
    hm = np.empty((H, W), dt)
    hmx = np.empty((H, W), dt)
    zr = np.empty(W, dt)
    zi = np.empty(W, dt)
    fa = np.empty(W, dt)
    mm = np.empty(W, dt)
    for i in range(H):
        for j in range(W):
            if m[i, j]:
                v = f[i, j] - mean
                # exp(-i(a_j + b_i)) = (cr + i ci)(rr + i ri)
                er = col_re[j] * row_re[i] - col_im[j] * row_im[i]
                ei = col_re[j] * row_im[i] + col_im[j] * row_re[i]
                zr[j] = v * er
                zi[j] = v * ei
                fa[j] = f[i, j]
                mm[j] = 1.0
            else:
                zr[j] = 0.0
                zi[j] = 0.0
                fa[j] = 0.0
                mm[j] = 0.0
        h0 = hre[i]
        h1 = him[i]
        h2 = ha[i]
        h3 = hm[i]
        h4 = hmx[i]
        h0[:] = 0.0
        h1[:] = 0.0
        h2[:] = 0.0
        h3[:] = 0.0
        h4[:] = 0.0
        for t in range(2 * R + 1):
            off = t - R
            w = g[t]
            wx = xg[t]
            jlo = max(0, -off)
            jhi = min(W, W - off)
            for j in range(jlo, jhi):
                h0[j] += w * zr[j + off]
                h1[j] += w * zi[j + off]
                h2[j] += w * fa[j + off]
                h3[j] += w * mm[j + off]
                h4[j] += wx * mm[j + off]
    b0 = np.empty(W, dt)
    b1 = np.empty(W, dt)
    b2 = np.empty(W, dt)
    b3 = np.empty(W, dt)
    b4 = np.empty(W, dt)
    b5 = np.empty(W, dt)
    for i in range(H):
        lo = max(0, i - R)
        hi = min(H, i + R + 1)
        b0[:] = 0.0
        b1[:] = 0.0
        b2[:] = 0.0
        b3[:] = 0.0
        b4[:] = 0.0
        b5[:] = 0.0
        for k in range(lo, hi):
            w = g[k - i + R]
            wx = xg[k - i + R]
            for j in range(W):
                hmk = hm[k, j]
                b0[j] += w * hre[k, j]
                b1[j] += w * him[k, j]
                b2[j] += w * ha[k, j]
                b3[j] += w * hmk
                b4[j] += w * hmx[k, j]
                b5[j] += wx * hmk
        re[i, :] = b0
        im[i, :] = b1
        a[i, :] = b2
        m0[i, :] = b3
        mx[i, :] = b4
        my[i, :] = b5


@njit(cache=True, nogil=True)
def edge_corrected_phase(re, im, m0, mx, my, cu, cv, off_i, off_j, min_support, theta, out_phase, out_mod):
    """Phase with the first-order edge correction and modulation 2|z|/m0.

    The demodulated phase theta = angle(re + i im) varies slowly; where the window is truncated by
    the mask its estimate is shifted by (local residual frequency) . (centroid offset); subtract it.
    (off_i, off_j): image position of element [0, 0] (the carrier phase is 2 pi c.x in image coordinates).
    """
    H, W = re.shape
    TWO_PI = 2.0 * math.pi
    for i in range(H):
        for j in range(W):
            theta[i, j] = math.atan2(im[i, j], re[i, j])
    for i in range(H):
        for j in range(W):
            s = m0[i, j]
            if s < min_support:
                out_phase[i, j] = np.nan
                out_mod[i, j] = 0.0
                continue
            out_mod[i, j] = 2.0 * math.sqrt(re[i, j] ** 2 + im[i, j] ** 2) / s
            t = theta[i, j]
            du = mx[i, j] / s
            dv = my[i, j] / s
            if abs(du) > 1e-3 or abs(dv) > 1e-3:
                # residual frequency from wrapped differences on the supported side
                j0, j1 = max(j - 1, 0), min(j + 1, W - 1)
                i0, i1 = max(i - 1, 0), min(i + 1, H - 1)
                if m0[i, j0] < min_support:
                    j0 = j
                if m0[i, j1] < min_support:
                    j1 = j
                if m0[i0, j] < min_support:
                    i0 = i
                if m0[i1, j] < min_support:
                    i1 = i
                bu = 0.0
                bv = 0.0
                if j1 > j0:
                    d = theta[i, j1] - theta[i, j0]
                    d -= TWO_PI * math.floor((d + math.pi) / TWO_PI)
                    bu = d / (j1 - j0)
                if i1 > i0:
                    d = theta[i1, j] - theta[i0, j]
                    d -= TWO_PI * math.floor((d + math.pi) / TWO_PI)
                    bv = d / (i1 - i0)
                t -= bu * du + bv * dv
            p = t + TWO_PI * (cu * (j + off_j) + cv * (i + off_i))
            out_phase[i, j] = p - TWO_PI * math.floor((p + math.pi) / TWO_PI)
