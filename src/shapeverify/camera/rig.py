"""The fringe-projection rig: two cameras and a projector in OpenCV's conventions (thesis §3.1, Paper III).

File format (``rig.json``; YAML with the same keys is read and written too)::

    {"units": "mm",
     "cameras": {"left":  {"K": [[fx,0,cx],[0,fy,cy],[0,0,1]], "dist": [k1,k2,p1,p2,k3],
                           "size": [W,H], "R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]},
                 "right": {"K": ..., "dist": ..., "size": [W,H], "R": ..., "T": ...}},
     "projector": {"K": ..., "dist": ..., "size": [W,H], "R": ..., "T": ...,
                   "pattern": {"type": "sinusoid", "direction": "columns", "period_px": 9.0}}}

Conventions, exactly:

* lengths in millimetres (``"units": "mm"``, the only unit accepted; a file without ``units`` is
  read as mm);
* the world frame is the **left camera's** frame, OpenCV axes: x right, y down, z forward (the
  viewing direction); the left camera therefore has ``R = I``, ``T = 0`` (other values are an error);
* every device maps a left-frame point to its own frame by ``x_device = R · x_left + T``
  (OpenCV's ``stereoCalibrate`` R, T); its centre is ``-Rᵀ T`` in the left frame;
* pixels: ``(u, v) = (column, row)``, pixel centres at integer coordinates ((0, 0) is the centre of
  the top-left pixel); ``size`` is ``[width, height]``;
* ``T`` may also be written as a column ``[[tx], [ty], [tz]]``; ``dist`` as 4 values (k3 = 0) or
  OpenCV's 8/12/14-value forms when the extra terms are zero;
* projection: ``x' = x/z, y' = y/z``, OpenCV distortion with ``dist = [k1, k2, p1, p2, k3]``
  (``r² = x'² + y'²``, radial ``1 + k1 r² + k2 r⁴ + k3 r⁶``, tangential p1, p2), then
  ``[u, v, 1]ᵀ = K [x'', y'', 1]ᵀ`` (``K`` upper triangular, ``K[2] = [0, 0, 1]``);
* the projector is an inverse camera with the same model.  Its pattern is a sinusoid whose phase
  at projector column ``u`` is ``2π u / period_px`` (``"direction": "rows"``: at row ``v``); the
  projected intensity is ``(1 + cos(phase)) / 2`` of full scale.

A rig from :func:`calibrate` (cameras only) may have ``"projector": null``; measuring needs one.

References
----------
Bergström (2011), thesis §3.1, Figures 2-3; Paper III.  OpenCV camera model:
https://docs.opencv.org/4.x/d9/d0c/group__calib3d.html
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from shapeverify.camera import _optics_kernels as _k
from shapeverify.errors import ShapeVerifyError
from shapeverify._renamed import grouped_keywords

__all__ = ["RigProjector", "Device", "Pattern", "Rig", "RigFormatError", "load_rig", "save_rig", "look_at_rig"]


class RigFormatError(ShapeVerifyError, ValueError):
    """A rig file or rig description is malformed; the message names the offending key."""


def _matrix(value, key, shape):
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise RigFormatError(f"{key} must be a numeric array of shape {shape}, got {value!r}") from None
    if a.shape != shape:
        raise RigFormatError(f"{key} must have shape {list(shape)}, got shape {list(a.shape)}")
    if not np.all(np.isfinite(a)):
        raise RigFormatError(f"{key} contains NaN or inf")
    return a


@dataclass(frozen=True, eq=False)
class Device:
    """A camera or projector: intrinsics, distortion, image size and pose relative to the left camera.

    Attributes
    ----------
    K : (3, 3) float64, pixels
    dist : (5,) float64, k1 k2 p1 p2 k3
    size : (int, int), (width, height) in pixels
    R : (3, 3) float64, rotation left -> device (a matrix within 1e-5 of a rotation, e.g. printed
        to a few digits, is replaced by the nearest rotation)
    T : (3,) float64, mm; ``x_device = R @ x_left + T``
    """

    K: np.ndarray
    dist: np.ndarray
    size: tuple
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    T: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        # vectors may come as columns ([[tx], [ty], [tz]], OpenCV's output); dist as 4 values
        # (k3 = 0) or OpenCV's longer forms whose extra (rational, prism, tilt) terms are zero
        for name in ("dist", "T"):
            v = getattr(self, name)
            try:
                a = np.asarray(v, dtype=np.float64).ravel()
            except (TypeError, ValueError):
                continue
            if name == "dist" and a.size == 4:
                a = np.append(a, 0.0)
            elif name == "dist" and a.size in (8, 12, 14):
                if np.any(a[5:] != 0):
                    raise RigFormatError("dist must be [k1, k2, p1, p2, k3]: the rational / thin-prism / tilt "
                                         f"terms of OpenCV's longer models are not supported (got {a.size} values)")
                a = a[:5]
            object.__setattr__(self, name, a if a.size in (3, 5) else v)
        for name, shape in (("K", (3, 3)), ("dist", (5,)), ("R", (3, 3)), ("T", (3,))):
            object.__setattr__(self, name, np.ascontiguousarray(_matrix(getattr(self, name), name, shape)))
        if not (self.K[0, 0] > 0 and self.K[1, 1] > 0 and self.K[1, 0] == 0 and np.allclose(self.K[2], [0, 0, 1])):
            raise RigFormatError(f"K must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, got {self.K.tolist()}")
        if not np.allclose(self.R @ self.R.T, np.eye(3), atol=1e-5) or np.linalg.det(self.R) <= 0:
            raise RigFormatError("R must be a rotation matrix (orthonormal, det +1)")
        if np.abs(self.R @ self.R.T - np.eye(3)).max() > 1e-13:  # e.g. printed to 7 digits
            u, _, vt = np.linalg.svd(self.R)
            object.__setattr__(self, "R", np.ascontiguousarray(u @ vt))  # the nearest rotation
        size = tuple(int(s) for s in np.asarray(self.size).ravel()) if np.size(self.size) == 2 else None
        if size is None or min(size) < 1 or not np.allclose(np.asarray(self.size, dtype=float), size):
            raise RigFormatError(f"size must be [width, height] in whole pixels, got {self.size!r}")
        from shapeverify.io.image_header import MAX_IMAGE_PIXELS

        if size[0] * size[1] > MAX_IMAGE_PIXELS:   # measuring allocates per-pixel arrays
            raise RigFormatError(f"size {list(size)} is {size[0] * size[1]:,} pixels; the limit is "
                                 f"{MAX_IMAGE_PIXELS:,} (is a digit too many?)")
        object.__setattr__(self, "size", size)

    @property
    def width(self) -> int:
        return self.size[0]

    @property
    def height(self) -> int:
        return self.size[1]

    @property
    def center(self) -> np.ndarray:
        """Projection centre in the left camera frame (3,), mm."""
        return -self.R.T @ self.T

    def project(self, points):
        """Left-frame points (N, 3) -> pixels (N, 2) and device depth z (N,) (NaN pixels behind)."""
        X = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
        uv, z = np.empty((len(X), 2)), np.empty(len(X))
        _k.project_many(self.K, self.dist, self.R, self.T, X, uv, z)
        return uv, z

    def normalized(self, pixels) -> np.ndarray:
        """Undistorted normalised coordinates ``(x/z, y/z)`` (N, 2) of pixels (N, 2)."""
        pix = np.ascontiguousarray(np.asarray(pixels, dtype=np.float64).reshape(-1, 2))
        out = np.empty_like(pix)
        _k.undistort_many(self.K, self.dist, pix, out)
        return out

    def rays(self, pixels):
        """Origins (N, 3) and unit directions (N, 3) in the left frame of the rays through pixels."""
        xy = self.normalized(pixels)
        d = np.column_stack([xy, np.ones(len(xy))]) @ self.R  # R^T applied to row vectors
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.broadcast_to(self.center, d.shape).copy(), d

    def pixel_grid(self) -> np.ndarray:
        """All pixel centres, row-major, (H*W, 2) as (u, v)."""
        v, u = np.mgrid[0:self.height, 0:self.width]
        return np.column_stack([u.ravel(), v.ravel()]).astype(np.float64)

    def to_dict(self) -> dict:
        return {"K": self.K.tolist(), "dist": self.dist.tolist(), "size": list(self.size),
                "R": self.R.tolist(), "T": self.T.tolist()}

    @classmethod
    def from_dict(cls, d, key) -> "Device":
        if not isinstance(d, dict):
            raise RigFormatError(f"{key} must be an object with keys K, dist, size, R, T, got {type(d).__name__}")
        missing = [k for k in ("K", "dist", "size", "R", "T") if k not in d]
        if missing:
            raise RigFormatError(f"{key} is missing key(s) {', '.join(missing)} (need K, dist, size, R, T)")
        try:
            return cls(d["K"], d["dist"], d["size"], d["R"], d["T"])
        except RigFormatError as e:
            raise RigFormatError(f"{key}.{e}") from None


@dataclass(frozen=True)
class Pattern:
    """The projected sinusoid: phase ``2π u / period_px`` at projector column u (or row v)."""

    period_px: float
    direction: str = "columns"
    type: str = "sinusoid"

    def __post_init__(self):
        if self.type != "sinusoid":
            raise RigFormatError(f"projector.pattern.type must be 'sinusoid', got {self.type!r}")
        if self.direction not in ("columns", "rows"):
            raise RigFormatError(f"projector.pattern.direction must be 'columns' or 'rows', got {self.direction!r}")
        p = float(self.period_px)
        if not (math.isfinite(p) and p >= 2.0):
            raise RigFormatError(f"projector.pattern.period_px must be a number >= 2 (pixels), got {self.period_px!r}")
        object.__setattr__(self, "period_px", p)

    def to_dict(self) -> dict:
        return {"type": self.type, "direction": self.direction, "period_px": self.period_px}


@dataclass(frozen=True, eq=False)
class Rig:
    """Two cameras and a projector; the world frame is the left camera's (see the module docstring)."""

    left: Device
    right: Device
    projector: Device | None = None
    pattern: Pattern | None = None

    def __post_init__(self):
        if not (np.allclose(self.left.R, np.eye(3), atol=1e-9) and np.allclose(self.left.T, 0.0, atol=1e-9)):
            raise RigFormatError("cameras.left must have R = identity and T = [0, 0, 0]: the world frame is the left camera's")
        if (self.projector is None) != (self.pattern is None):
            raise RigFormatError("projector and projector.pattern go together")
        if np.linalg.norm(self.right.center) < 1e-9:
            raise RigFormatError("cameras.right has the left camera's centre: the stereo baseline is zero")

    def __repr__(self) -> str:
        b = np.linalg.norm(self.right.center)
        p = "none" if self.pattern is None else f"{self.projector.width}x{self.projector.height}, period {self.pattern.period_px:g} px"
        return (f"Rig(left {self.left.width}x{self.left.height}, right {self.right.width}x{self.right.height}, "
                f"baseline {b:.4g} mm, projector {p})")

    def to_dict(self) -> dict:
        out = {"units": "mm", "cameras": {"left": self.left.to_dict(), "right": self.right.to_dict()},
               "projector": None}
        if self.projector is not None:
            out["projector"] = dict(self.projector.to_dict(), pattern=self.pattern.to_dict())
        return out

    @classmethod
    def from_dict(cls, d) -> "Rig":
        if not isinstance(d, dict):
            raise RigFormatError(f"a rig must be an object with keys units, cameras, projector, got {type(d).__name__}")
        units = d.get("units", "mm")  # absent: millimetres, the format's only unit
        if units != "mm":
            raise RigFormatError(f"units must be \"mm\" (all lengths in millimetres), got {units!r}")
        cams = d.get("cameras")
        if not isinstance(cams, dict) or "left" not in cams or "right" not in cams:
            raise RigFormatError("cameras must be an object with keys left and right")
        left = Device.from_dict(cams["left"], "cameras.left")
        right = Device.from_dict(cams["right"], "cameras.right")
        proj = d.get("projector", None)
        if proj is None:
            return cls(left, right)
        if not isinstance(proj, dict) or "pattern" not in proj:
            raise RigFormatError("projector must be an object with keys K, dist, size, R, T, pattern")
        pat = proj["pattern"]
        if not isinstance(pat, dict) or "period_px" not in pat:
            raise RigFormatError("projector.pattern must be an object with keys type, direction, period_px")
        pattern = Pattern(pat["period_px"], pat.get("direction", "columns"), pat.get("type", "sinusoid"))
        return cls(left, right, Device.from_dict(proj, "projector"), pattern)

    def with_period(self, period_px: float) -> "Rig":
        """The same rig with another pattern period (pixels)."""
        return Rig(self.left, self.right, self.projector, Pattern(period_px, self.pattern.direction))


def load_rig(path) -> Rig:
    """Read a rig from ``.json`` or ``.yaml``/``.yml`` (see the module docstring for the keys).

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    RigFormatError
        Not UTF-8 text, not valid JSON/YAML (hostile YAML too: aliases beyond a small budget,
        deep nesting), a number Python cannot read, or keys and values that do not describe a
        rig; the message names the file.
    """
    from shapeverify.io.yaml_safe import YamlInputError, load_yaml

    path = Path(path)
    is_yaml = path.suffix.lower() in (".yaml", ".yml")
    if path.is_dir():
        raise RigFormatError(f"{path}: is a directory; give the rig file (rig.json or rig.yaml)")
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise RigFormatError(f"{path}, line {line}: not UTF-8 text (byte 0x{raw[exc.start]:02x}); a "
                             "rig file is JSON or YAML text: save it as UTF-8") from None
    if is_yaml:
        try:
            data = load_yaml(text, str(path))
        except YamlInputError as e:
            raise RigFormatError(str(e)) from None
    else:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise RigFormatError(f"{path}, line {e.lineno}: not valid JSON: {e.msg}") from None
        except (ValueError, RecursionError) as e:  # a 5,000-digit number; nesting too deep
            why = "nested too deeply" if isinstance(e, RecursionError) else str(e)[:120]
            raise RigFormatError(f"{path}: not valid JSON: {why}") from None
    try:
        return Rig.from_dict(data)
    except RigFormatError as e:
        raise RigFormatError(f"{path}: {e}") from None
    except (TypeError, ValueError, OverflowError) as e:   # numbers numpy/Python cannot take
        raise RigFormatError(f"{path}: not a rig: {str(e)[:160]}") from None


def save_rig(rig: Rig, path) -> Path:
    """Write a rig to ``.json`` (default) or ``.yaml``/``.yml``; returns the path."""
    path = Path(path)
    if path.suffix.lower() in (".yaml", ".yml"):
        import yaml
        path.write_text(yaml.safe_dump(rig.to_dict(), sort_keys=False))
    else:
        text = json.dumps(rig.to_dict(), indent=1)
        # one line per matrix row / vector: [[1, 0, 0], ...] reads like the format in the docs
        text = re.sub(r"\[\s+([^\[\]]*?)\s+\]", lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]", text)
        path.write_text(text + "\n")
    return path


def _look_at(eye, target, up):
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.vstack([x, y, z])  # rows: device axes in the parent frame -> R_device_parent


@dataclass(frozen=True)
class RigProjector:
    """The projector of :func:`look_at_rig` (its ``projector=``; the loose keywords of these
    names still work, with a DeprecationWarning)."""

    projector_size: tuple = (1280, 800)
    projector_fov_deg: float = 26.0
    period_px: float = 9.0


@grouped_keywords("projector", RigProjector)
def look_at_rig(target, distance: float, baselines=(-90.0, 130.0), width: int = 1000,
                height: int = 1000, fov_deg: float = 24.0, dist=(0.0,) * 5,
                focal_px: float | None = None,
                projector: RigProjector = RigProjector()) -> tuple[Rig, np.ndarray]:
    """A converging rig looking at ``target`` from ``distance`` mm (for simulation and tests).

    The projector sits at the origin of a scene frame and looks down -z at ``target`` (given in that
    frame); the cameras sit at x = ``baselines`` (mm, on opposite sides) at the same height.
    ``focal_px`` (cameras) overrides ``fov_deg``: a smaller sensor with the same lens sees a crop.
    Unequal baselines make the stereo check of the fringe order decisive on flat parts (with equal
    ones a wrong order is consistent on a plane parallel to the baseline).

    Returns
    -------
    rig : Rig
    T_left_scene : (4, 4) float64
        Maps scene coordinates to the left camera frame (the pose of the scene in the rig frame).
    """
    projector_size = projector.projector_size
    projector_fov_deg = projector.projector_fov_deg
    period_px = projector.period_px
    target = np.asarray(target, dtype=np.float64)
    eye_p = target + np.array([0.0, 0.0, distance])
    up = np.array([0.0, -1.0, 0.0])
    poses = {}
    for name, bx in (("left", baselines[0]), ("right", baselines[1]), ("projector", 0.0)):
        eye = eye_p + np.array([bx, 0.0, 0.0])
        Rd = _look_at(eye, target, up)  # device <- scene
        poses[name] = (Rd, -Rd @ eye)
    R_l, t_l = poses["left"]

    def device(name, w, h, fov):
        Rd, td = poses[name]
        R = Rd @ R_l.T  # device <- left
        T = td - R @ t_l
        f = 0.5 * w / math.tan(math.radians(fov) / 2) if (focal_px is None or name == "projector") else focal_px
        K = [[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]]
        return Device(K, dist if name != "projector" else (0.0,) * 5, (w, h), R, T)

    left = Device(device("left", width, height, fov_deg).K, dist, (width, height))
    rig = Rig(left, device("right", width, height, fov_deg),
              device("projector", projector_size[0], projector_size[1], projector_fov_deg), Pattern(period_px))
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R_l, t_l
    return rig, T
