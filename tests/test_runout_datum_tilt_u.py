"""NIST CTC 05 GT9 (total runout 0.0508 of the bore face:37, r 127 mm, about datum A, a boss
r 31.75 mm, 190 mm long, whose middle is 280-370 mm from the bore) read 0.281 +- 0.209 on a
perfect independent scan (2 mm, 0.02 mm noise, random pose) and failed: the noise alone
reads 0.165, the rest was datum A's mating cylinder turned by its extreme noisy points,
which moves the bore 280-370 mm away.  The runout's U counted the datum's turn as
``mating_centre_u * |q| / L`` (0.070 there) while the turn at the ends of a mating
cylinder's length is already ~1.3 x its offset, so the bore moved up to 2.3 x as much.

The brute force: a Monte Carlo of the datum's mating cylinder (``cylinders_zone``, the fit
``drf`` makes) on noisy points of the nominal datum, and the range of the face's own nominal
points' deviations from the CAD face about the fitted axis (what the indicator reads on a
perfect face).  :func:`runout_datum_u` must cover >= 95 % of those ranges and stay within 2 x
their 95.45 % quantile."""
from __future__ import annotations

import numpy as np
import pytest

from shapeverify.characteristics.gdt import mating_centre_u, runout_datum_u
from shapeverify.characteristics.gdt_zones import cylinders_zone

pytestmark = pytest.mark.slow          # ~10 s: 2 x 150 fits of 1000 points


def _datum_points(rng, n, r, z0, z1, noise):
    phi = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(z0, z1, n)
    rr = r + rng.normal(0, noise, n)
    return np.column_stack([rr * np.cos(phi), rr * np.sin(phi), z])


def _monte_carlo(kind, r, z0, z1, face, normals, reps=150, n=1000, noise=0.02, seed=3):
    """Range of the face points' normal deviations about each fitted datum axis."""
    rng = np.random.default_rng(seed)
    mid = np.array([0.0, 0.0, 0.5 * (z0 + z1)])
    out = []
    for _ in range(reps):
        _, p, a, _ = cylinders_zone(_datum_points(rng, n, r, z0, z1, noise), mid,
                                    np.array([0.0, 0.0, 1.0]), kind)
        a = a if a[2] > 0 else -a
        # the rigid motion that puts the fitted axis (p, a) on the nominal one (the z axis
        # through the origin): the DRF's correction; the face's nominal points moved by it
        v = np.cross(a, [0.0, 0.0, 1.0])
        s, c = np.linalg.norm(v), a[2]
        K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        R = np.eye(3) + K + K @ K * ((1 - c) / s ** 2) if s > 0 else np.eye(3)
        Y = (face - p) @ R.T
        if np.allclose(np.abs(normals[:, 2]), 1.0):       # a plane square to the axis
            dev = Y[:, 2] - face[:, 2]
        else:                                             # a coaxial cylinder
            dev = np.hypot(Y[:, 0], Y[:, 1]) - np.hypot(face[:, 0], face[:, 1])
        out.append(float(np.ptp(dev)))
    return np.array(out)


def _case(kind):
    rng = np.random.default_rng(11)
    if kind == "circumscribed":          # CTC 05 GT9: the bore face:37 about datum A (a boss)
        r, z0, z1 = 31.75, 285.76, 476.25
        phi, z = rng.uniform(0, 2 * np.pi, 4000), rng.uniform(9.53, 101.6, 4000)
        face = np.column_stack([127.0 * np.cos(phi), 127.0 * np.sin(phi), z])
        normals = -np.column_stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)])
    else:                                # CTC 05 GT10: the floor face:8 about datum B (a bore)
        r, z0, z1 = 127.0, 9.53, 101.6
        phi, rho = rng.uniform(0, 2 * np.pi, 4000), np.sqrt(rng.uniform(136.5 ** 2, 279.4 ** 2, 4000))
        face = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), np.zeros_like(phi)])
        normals = np.tile([0.0, 0.0, -1.0], (len(phi), 1))
    return r, z0, z1, face, normals


@pytest.mark.parametrize("kind", ["circumscribed", "inscribed"])
def test_runout_u_covers_the_datum_axis_turn_at_a_far_face(kind):
    r, z0, z1, face, normals = _case(kind)
    n, noise = 1000, 0.02
    ranges = _monte_carlo(kind, r, z0, z1, face, normals, n=n, noise=noise)
    mid = np.array([0.0, 0.0, 0.5 * (z0 + z1)])
    U = runout_datum_u(n, noise, 2.0, face, normals, mid, [0, 0, 1.0], z1 - z0)
    q = float(np.quantile(ranges, 0.9545))
    assert np.mean(ranges <= U) >= 0.95, (U, q)
    assert U <= 2.0 * q, (U, q)
    # what the runout counted before: the offset's U times |q| / L (at least 1)
    old = mating_centre_u(n, noise, 2.0) * max(
        1.0, float(np.linalg.norm(face - mid, axis=1).max()) / (z1 - z0))
    assert np.mean(ranges <= old) < 0.9, (old, q)


def test_runout_u_of_a_datum_whose_direction_a_plane_sets_is_its_offset_alone():
    """With A|B (a plane sets the axis's direction) only the offset counts: a coaxial cylinder
    reads it fully, a face square to the axis not at all."""
    u0 = mating_centre_u(500, 0.02, 2.0)
    feet = np.array([[50.0, 0, 10], [0, 50.0, 300]])
    cyl = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    assert runout_datum_u(500, 0.02, 2.0, feet, cyl, [0, 0, 0], [0, 0, 1], 0.0) == pytest.approx(u0)
    plane = np.array([[0, 0, 1.0], [0, 0, 1.0]])
    assert runout_datum_u(500, 0.02, 2.0, feet, plane, [0, 0, 0], [0, 0, 1], 0.0) == 0.0
