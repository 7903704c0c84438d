"""Stereo camera calibration from images of a planar chessboard, with OpenCV.

Corners: ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix``; intrinsics and distortion
(k1, k2, p1, p2, k3) per camera: ``cv2.calibrateCamera``; the right camera's pose relative to the
left: ``cv2.stereoCalibrate`` with the intrinsics fixed.  The result is a
:class:`~shapeverify.camera.rig.Rig` in the conventions of :mod:`shapeverify.camera.rig`
(``x_right = R x_left + T``, mm) with the RMS reprojection errors (pixels).

:func:`render_chessboard` draws the target as a camera with exact projection sees it (for tests).

References
----------
Z. Zhang, IEEE TPAMI 22 (2000) 1330-1334.  OpenCV calib3d documentation.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from shapeverify.camera.rig import Device, Rig

__all__ = ["Calibration", "calibrate", "find_corners", "board_points", "render_chessboard"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, repr=False)
class Calibration:
    """Result of :func:`calibrate`.

    Attributes
    ----------
    rig : Rig
        Left and right cameras (and the projector passed in, if any).
    rms_left, rms_right : float
        RMS reprojection error (pixels) of each camera's own calibration.
    rms_stereo : float
        RMS reprojection error (pixels) of the stereo calibration over both cameras.
    views : int
        Image pairs whose corners were found in both images.
    rejected : tuple of int
        Indices of pairs where the board was not found.
    """

    rig: Rig
    rms_left: float
    rms_right: float
    rms_stereo: float
    views: int
    rejected: tuple = ()

    def __repr__(self):
        return (f"Calibration(views={self.views}, reprojection rms: left {self.rms_left:.4f} px, "
                f"right {self.rms_right:.4f} px, stereo {self.rms_stereo:.4f} px)")


def board_points(pattern, square_mm) -> np.ndarray:
    """Inner-corner coordinates (N, 3) on the board (z = 0, mm), in OpenCV's row-major order."""
    cols, rows = pattern
    g = np.zeros((rows * cols, 3), np.float32)
    g[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * float(square_mm)
    return g


def _gray(image, name):
    import cv2

    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.ndim != 2:
        raise ValueError(f"{name}: need a grey or colour image, got shape {img.shape}")
    if img.dtype != np.uint8:
        top = float(img.max()) or 1.0
        img = np.clip(np.round(img.astype(np.float64) * (255.0 / top)), 0, 255).astype(np.uint8)
    return img


def find_corners(image, pattern):
    """Sub-pixel inner corners (N, 2) float32 of a chessboard with ``pattern = (cols, rows)``, or None."""
    import cv2

    img = _gray(image, "image")
    found, corners = cv2.findChessboardCorners(img, tuple(int(p) for p in pattern),
                                               cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found:
        return None
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    corners = cv2.cornerSubPix(img, corners, (7, 7), (-1, -1), crit)
    return corners.reshape(-1, 2)


def calibrate(left_images, right_images, pattern=(9, 6), square_mm=10.0, projector=None, pattern_fringe=None,
              fix_k3=False) -> Calibration:
    """Calibrate a stereo pair from image pairs of a planar chessboard.

    Parameters
    ----------
    left_images, right_images : sequences of (H, W) or (H, W, 3) arrays
        Image ``i`` of both lists shows the board in the same position.
    pattern : (int, int)
        Inner corners per row and column ``(cols, rows)`` as in OpenCV.
    square_mm : float
        Side of one square (mm).
    projector : Device or None
        Projector to put into the rig (calibrated elsewhere); needs ``pattern_fringe``.
    pattern_fringe : Pattern or None
    fix_k3 : bool
        Keep k3 = 0 (recommended for lenses with little distortion and few views).

    Returns
    -------
    Calibration

    Raises
    ------
    ValueError
        Different numbers of left and right images, different sizes, fewer than 3 usable pairs.
    """
    import cv2

    left_images, right_images = list(left_images), list(right_images)
    if len(left_images) != len(right_images):
        raise ValueError(f"need as many left as right images (pairs), got {len(left_images)} and {len(right_images)}")
    if not square_mm > 0:
        raise ValueError(f"square_mm must be positive, got {square_mm}")
    obj = board_points(pattern, square_mm)
    objs, pl, pr, rejected = [], [], [], []
    size_l = size_r = None
    for i, (a, b) in enumerate(zip(left_images, right_images)):
        a, b = _gray(a, f"left image {i}"), _gray(b, f"right image {i}")
        sl, sr = (a.shape[1], a.shape[0]), (b.shape[1], b.shape[0])
        if size_l is None:
            size_l, size_r = sl, sr
        elif sl != size_l or sr != size_r:
            raise ValueError(f"image pair {i} has sizes {sl}, {sr}; the first pair has {size_l}, {size_r}")
        ca, cb = find_corners(a, pattern), find_corners(b, pattern)
        if ca is None or cb is None:
            rejected.append(i)
            continue
        objs.append(obj)
        pl.append(ca.astype(np.float32))
        pr.append(cb.astype(np.float32))
    if len(objs) < 3:
        raise ValueError(f"the {pattern[0]} x {pattern[1]} chessboard was found in only {len(objs)} image pair(s); "
                         "need at least 3 (check --pattern: inner corners per row x per column)")
    flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 200, 1e-12)
    rms_l, K1, d1, _, _ = cv2.calibrateCamera(objs, pl, size_l, None, None, flags=flags, criteria=crit)
    rms_r, K2, d2, _, _ = cv2.calibrateCamera(objs, pr, size_r, None, None, flags=flags, criteria=crit)
    rms_s, K1, d1, K2, d2, R, T, _, _ = cv2.stereoCalibrate(objs, pl, pr, K1, d1, K2, d2, size_l,
                                                            flags=cv2.CALIB_FIX_INTRINSIC, criteria=crit)
    log.info("calibration: %d views, rms left %.4f right %.4f stereo %.4f px", len(objs), rms_l, rms_r, rms_s)
    left = Device(K1, np.asarray(d1).ravel()[:5], size_l)
    right = Device(K2, np.asarray(d2).ravel()[:5], size_r, R, np.asarray(T).ravel())
    rig = Rig(left, right, projector, pattern_fringe)
    return Calibration(rig, float(rms_l), float(rms_r), float(rms_s), len(objs), tuple(rejected))


def render_chessboard(device: Device, T_left_board, pattern=(9, 6), square_mm=10.0, supersample=3,
                      dark=30.0, light=220.0):
    """Image (H, W) uint8 of a chessboard seen by ``device``, by exact ray casting.

    The board lies in its own z = 0 plane with inner corner (i, j) at ``(i, j) * square_mm``
    (:func:`board_points`); it has ``cols + 1`` x ``rows + 1`` squares and a one-square white margin.
    ``T_left_board`` (4, 4) maps board coordinates to the left camera frame; a list of poses gives a
    list of images (the pixel rays are computed once).  Each pixel averages ``supersample``² rays.
    """
    from shapeverify.camera import _optics_kernels as _k

    poses = np.asarray(T_left_board, dtype=np.float64)
    single = poses.ndim == 2
    poses = poses[None] if single else poses
    cols, rows = pattern
    W, H = device.size
    base = device.pixel_grid()
    s = int(supersample)
    dirs = np.stack([device.rays(base + np.array([(i + 0.5) / s - 0.5, (j + 0.5) / s - 0.5]))[1]
                     for i in range(s) for j in range(s)])
    images = []
    for T in poses:
        out = np.empty(W * H)
        _k.board_image(dirs, device.center, np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]),
                       int(cols), int(rows), float(square_mm), float(dark), float(light), 0.15 * (dark + light), out)
        images.append(np.clip(np.round(out), 0, 255).astype(np.uint8).reshape(H, W))
    return images[0] if single else images
