"""A tangent datum plane on a noisy scan rests on the noise's extremes (FTC 07's datum A sat
0.067 mm outside a perfect face at 1 mm, 0.02 mm noise): the filter of
:mod:`shapeverify.characteristics.datum_filter` (each point -> the centroid of its
neighbours within a radius, ISO 17450's filtration before the association) must leave a flat
face where it is (edges and tilt included) and bring the tangent plane back to within ~1.5
noise sigmas of the surface.  (The filter is off by default, ``datum_filter.RADIUS = 0``: these
tests call it with its radius.)"""
import numpy as np

from shapeverify.characteristics.datum_filter import filter_plane_points
from shapeverify.characteristics.drf import DatumFeature, fit_drf


def _face(n, sigma, seed, size=(80.0, 40.0)):
    rng = np.random.default_rng(seed)
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]       # any orientation
    p0 = np.array([12.0, -40.0, 7.0])
    uv = rng.uniform([0, 0], size, (n, 2))
    z = rng.normal(0.0, sigma, n)
    return np.c_[uv, z] @ R.T + p0, R, p0, z


def test_filter_is_the_brute_force_neighbour_centroid():
    X, _, _, _ = _face(600, 0.02, 1, size=(20.0, 10.0))
    F = filter_plane_points(X, 1.5)
    D = np.linalg.norm(X[:, None, :] - X[None, :, :], axis=2)
    brute = np.array([X[D[i] <= 1.5].mean(axis=0) for i in range(len(X))])
    assert np.abs(F - brute).max() < 1e-9


def test_filter_moves_no_point_off_an_exact_tilted_plane():
    X, R, p0, _ = _face(5000, 0.0, 2)
    F = filter_plane_points(X, 2.5)
    assert np.abs((F - p0) @ R[:, 2]).max() < 1e-11     # edges included
    assert np.abs(F - X).max() > 0.1                     # it did move them in the plane


def test_filtered_tangent_plane_is_near_the_surface_not_the_noise_extreme():
    sigma = 0.02
    X, R, p0, z = _face(3200, sigma, 3)                  # 80 x 40 mm at 1 mm
    n0 = R[:, 2]

    def offset(P):
        f = DatumFeature("A", "plane", p0, n0, P)
        drf = fit_drf([f], size=100.0)
        d = drf.datums[0]
        # where the fitted plane crosses the face's middle, along the true normal
        mid = p0 + R[:, :2] @ np.array([40.0, 20.0])
        return float((mid - drf.apply(mid[None])[0]) @ n0)

    raw = offset(X)
    filt = offset(filter_plane_points(X, 2.5))
    # the raw tangent plane: near the largest noise deviate (brute force), > 3 sigma out
    assert raw > 3.0 * sigma and abs(raw - z.max()) < 1.5 * sigma
    assert 0.0 < filt < 1.5 * sigma
