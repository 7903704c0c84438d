"""Phase unwrapping regularised by the CAD model for dual-wavelength holography (Paper V).

The measurement frame is the camera's world frame (the scan frame): the part sits there at pose
``inv(T_model_scan)``. For a pose, the camera module intersects every pixel ray exactly with the CAD
model and the optical path ``|X - S| + |X - C|`` of each hit gives the predicted unwrapped phase.
The regularised unwrapping recovers steps larger than half a fringe from that prediction; the
resulting 3D points are registered to the model, which corrects the pose, and the prediction is
made again (for the small pose corrections the stored view is updated by a few Newton steps per
pixel, Paper IV) until pose and phase stop changing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from shapeverify.phase.holography import phase_to_points, points_to_phase
from shapeverify._renamed import grouped_keywords
from shapeverify.phase.regularised import IterativeUnwrap, UnwrapStop, iterate_unwrap


@dataclass(frozen=True)
class HolographySetup:
    """Geometry of a dual-wavelength holography measurement.

    Parameters
    ----------
    camera : shapeverify.camera.PinholeCamera
        The camera, posed in the measurement (scan) frame.
    synthetic : float
        Synthetic wavelength Λ = λ1 λ2 / |λ1 − λ2| in mm.
    source : (3,) array_like or None
        Point source of the divergent illumination (None: at the camera centre).
    path_offset : float
        Optical path length (mm) at zero phase.
    """

    camera: object
    synthetic: float
    source: tuple | None = None
    path_offset: float = 0.0


class _Predictor:
    """Predicted unwrapped phase for a pose, reusing one exact view across small pose changes."""

    def __init__(self, prep, setup: HolographySetup):
        self.prep, self.setup = prep, setup
        self.view = None

    def __call__(self, T_model_scan) -> np.ndarray:
        from shapeverify.camera import depth_map, make_view

        T_world_model = np.linalg.inv(np.asarray(T_model_scan, dtype=np.float64))
        if self.view is None:
            self.view = make_view(self.prep, self.setup.camera, T_world_model)
            hits = self.view.hits
        else:
            hits = depth_map(self.view, T_world_model @ np.linalg.inv(self.view.T_world_model))
        cam = self.setup.camera
        pts = np.where(hits.hit[:, None], hits.points, 0.0) @ T_world_model[:3, :3].T + T_world_model[:3, 3]
        phi = points_to_phase(pts, self.setup.synthetic, center=cam.center, source=self.setup.source,
                              path_offset=self.setup.path_offset)
        return np.where(hits.hit, phi, np.nan).reshape(cam.height, cam.width)


def predict_phase(prep, setup: HolographySetup, T_model_scan) -> np.ndarray:
    """Unwrapped phase (H, W) the camera should see of the CAD model at pose ``T_model_scan``
    (NaN where the model is not seen)."""
    return _Predictor(prep, setup)(T_model_scan)


def points_from_phase(phi, setup: HolographySetup) -> np.ndarray:
    """3D points (N, 3) in the measurement frame of the pixels with a finite unwrapped phase."""
    cam = setup.camera
    phi = np.asarray(phi, dtype=np.float64)
    if phi.shape != (cam.height, cam.width):
        raise ValueError(f"phase shape {phi.shape} does not match the camera image {(cam.height, cam.width)}")
    _, d = cam.pixel_rays()
    pts = phase_to_points(phi.ravel(), setup.synthetic, d, center=cam.center, source=setup.source,
                          path_offset=setup.path_offset)
    return pts[np.all(np.isfinite(pts), axis=1)]


@grouped_keywords("stop", UnwrapStop)
def unwrap_with_cad(psi, prep, setup: HolographySetup, T_model_scan, *, mask=None, quality=None,
                    method: str = "auto", register_kwargs: dict | None = None,
                    stop: UnwrapStop = UnwrapStop(10, 1e-5, 1e-3)) -> IterativeUnwrap:
    """Unwrap a wrapped phase map with the CAD model as prior, refining the part's pose.

    Parameters
    ----------
    psi : (H, W) float
        Wrapped phase (radians) of the camera image.
    prep : Prepared
        The prepared CAD model (closest points for registration, exact surfaces for the rays).
    setup : HolographySetup
    T_model_scan : (4, 4)
        Approximate pose of the part (model = R @ scan + t).
    register_kwargs : dict, optional
        Passed to :func:`shapeverify.register` (default: point-to-plane, Tukey).
    stop : UnwrapStop
        ``max_iterations`` (10), and the convergence: pose change per iteration below both
        ``rotation_tol`` (1e-5 rad) and ``translation_tol`` (1e-3 mm) and no pixel changed.
        The defaults sit above the scatter of registering noisy points again.  (The loose
        keywords of these names still work, with a DeprecationWarning.)

    Notes
    -----
    What the prior can and cannot do: it places every region's 2π multiple, so steps of any
    height between regions are recovered, but only if the initial pose predicts the absolute
    phase within half a fringe, i.e. the part's position along the viewing direction is known
    within about Λ/4 (0.25 mm for Λ = 1 mm). A start further off converges to a pose shifted by
    a whole fringe (Λ/2 along the rays) with every pixel off by the same 2π: an ambiguity that
    the measurement itself cannot resolve. In-plane errors and rotations only misplace edges and
    are corrected by the iteration.

    Returns
    -------
    IterativeUnwrap
        ``.phase`` the unwrapped phase, ``.T_model_scan`` the refined pose, and the history.

    References
    ----------
    Bergström 2011, Paper V (CAD-regularised phase unwrapping), Paper IV (small-motion update).
    """
    from shapeverify.registration import register

    kwargs = dict(register_kwargs or {})
    state = {"T": np.asarray(T_model_scan, dtype=np.float64)}

    def _register(points: np.ndarray) -> np.ndarray:
        reg = register(points, prep, init=state["T"], **kwargs)
        state["T"] = reg.T_model_scan
        return reg.T_model_scan

    return iterate_unwrap(psi, _Predictor(prep, setup), lambda phi: points_from_phase(phi, setup), _register,
                          T_model_scan, mask=mask, quality=quality, method=method, stop=stop)
