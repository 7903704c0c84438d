"""Pinhole camera with optional radial distortion (OpenCV conventions).

Camera frame: x right, y down, z forward (the viewing direction). A world point X maps to camera
coordinates ``Xc = R^T (X - c)`` where ``T_world_camera = [[R, c], [0, 1]]``; its normalised image
coordinates are ``(x, y) = (Xc/Zc, Yc/Zc)``, distorted by ``(1 + k1 r^2 + k2 r^4)``, and pixels are
``(fx x_d + cx, fy y_d + cy)``. Pixel (0, 0) is the centre of the top-left pixel.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from shapeverify._arrays import check_points


@dataclass(frozen=True)
class PinholeCamera:
    """A calibrated pinhole camera.

    Parameters
    ----------
    fx, fy : float
        Focal lengths in pixels.
    cx, cy : float
        Principal point in pixels.
    width, height : int
        Image size in pixels.
    T_world_camera : (4, 4) float64
        Pose: maps camera coordinates to world (model) coordinates.
    k1, k2 : float
        Radial distortion coefficients.

    Examples
    --------
    >>> cam = PinholeCamera(500, 500, 320, 240, 640, 480)
    >>> cam.project(np.array([[0.0, 0.0, 100.0]]))[0].round(6).tolist()
    [[320.0, 240.0]]
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    T_world_camera: np.ndarray = field(default_factory=lambda: np.eye(4))
    k1: float = 0.0
    k2: float = 0.0

    def __post_init__(self):
        T = np.asarray(self.T_world_camera, dtype=np.float64)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"T_world_camera must be a finite (4, 4) matrix, got shape {T.shape}")
        R = T[:3, :3]
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
            raise ValueError("T_world_camera[:3, :3] must be a rotation (orthonormal, det +1)")
        for name in ("fx", "fy"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be a positive focal length in pixels, got {getattr(self, name)}")
        if int(self.width) < 1 or int(self.height) < 1:
            raise ValueError(f"image size must be positive, got {self.width} x {self.height}")
        object.__setattr__(self, "T_world_camera", T)

    def __repr__(self) -> str:
        c = np.round(self.center, 3).tolist()
        return (f"PinholeCamera(f=({self.fx:g}, {self.fy:g}), c=({self.cx:g}, {self.cy:g}), "
                f"{self.width}x{self.height}, center={c}, k=({self.k1:g}, {self.k2:g}))")

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 0.0, 1.0), fov_deg: float = 40.0, width: int = 640,
                height: int = 480, k1: float = 0.0, k2: float = 0.0) -> "PinholeCamera":
        """A camera at ``eye`` looking at ``target`` with a horizontal field of view ``fov_deg``."""
        eye, target, up = (np.asarray(a, dtype=np.float64) for a in (eye, target, up))
        z = target - eye
        if np.linalg.norm(z) == 0:
            raise ValueError("eye and target coincide")
        z /= np.linalg.norm(z)
        x = np.cross(z, up)
        if np.linalg.norm(x) < 1e-9:
            raise ValueError("up is parallel to the viewing direction; choose another up vector")
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        T = np.eye(4)
        T[:3, :3] = np.column_stack([x, y, z])
        T[:3, 3] = eye
        f = 0.5 * width / np.tan(np.radians(fov_deg) / 2)
        return cls(f, f, (width - 1) / 2, (height - 1) / 2, width, height, T, k1, k2)

    @property
    def center(self) -> np.ndarray:
        """Projection centre in world coordinates (3,)."""
        return self.T_world_camera[:3, 3].copy()

    def _distort(self, xy: np.ndarray) -> np.ndarray:
        if self.k1 == 0 and self.k2 == 0:
            return xy
        r2 = (xy ** 2).sum(axis=1, keepdims=True)
        return xy * (1 + self.k1 * r2 + self.k2 * r2 ** 2)

    def _undistort(self, xy_d: np.ndarray) -> np.ndarray:
        if self.k1 == 0 and self.k2 == 0:
            return xy_d
        xy = xy_d.copy()
        for _ in range(50):  # fixed-point iteration, converges for moderate distortion
            r2 = (xy ** 2).sum(axis=1, keepdims=True)
            new = xy_d / (1 + self.k1 * r2 + self.k2 * r2 ** 2)
            if np.max(np.abs(new - xy)) < 1e-14:
                xy = new
                break
            xy = new
        return xy

    def to_camera(self, points) -> np.ndarray:
        """World points (N, 3) -> camera coordinates (N, 3)."""
        p = check_points(points, single=False)
        R, c = self.T_world_camera[:3, :3], self.T_world_camera[:3, 3]
        return (p - c) @ R

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Project world points.

        Returns
        -------
        pixels : (N, 2) float64 (u = column, v = row)
        depth : (N,) float64, the z coordinate in the camera frame (mm); <= 0 is behind the camera
        """
        pc = self.to_camera(points)
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = pc[:, :2] / z[:, None]
        xy = self._distort(xy)
        pix = np.column_stack([self.fx * xy[:, 0] + self.cx, self.fy * xy[:, 1] + self.cy])
        return pix, z

    def rays(self, pixels) -> tuple[np.ndarray, np.ndarray]:
        """Rays through pixel coordinates (N, 2): origins (N, 3) and unit directions (N, 3), world frame."""
        pix = np.asarray(pixels, dtype=np.float64)
        if pix.ndim != 2 or pix.shape[1] != 2 or not np.all(np.isfinite(pix)):
            raise ValueError(f"pixels must be a finite (N, 2) array, got shape {pix.shape}")
        xy_d = np.column_stack([(pix[:, 0] - self.cx) / self.fx, (pix[:, 1] - self.cy) / self.fy])
        xy = self._undistort(xy_d)
        d = np.column_stack([xy, np.ones(len(xy))]) @ self.T_world_camera[:3, :3].T
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.broadcast_to(self.center, d.shape).copy(), d

    def unproject(self, pixels, depth) -> np.ndarray:
        """World points at camera-frame depth ``depth`` (N,) along the rays of ``pixels`` (N, 2)."""
        pix = np.asarray(pixels, dtype=np.float64)
        depth = np.asarray(depth, dtype=np.float64).reshape(-1)
        xy = self._undistort(np.column_stack([(pix[:, 0] - self.cx) / self.fx, (pix[:, 1] - self.cy) / self.fy]))
        pc = np.column_stack([xy * depth[:, None], depth])
        return pc @ self.T_world_camera[:3, :3].T + self.center

    def pixel_grid(self) -> np.ndarray:
        """Pixel centres of the whole image, row-major: (height * width, 2) as (u, v)."""
        v, u = np.mgrid[0:self.height, 0:self.width]
        return np.column_stack([u.ravel(), v.ravel()]).astype(np.float64)

    def pixel_rays(self) -> tuple[np.ndarray, np.ndarray]:
        """Rays of every pixel, row-major (height * width, 3) each."""
        return self.rays(self.pixel_grid())
