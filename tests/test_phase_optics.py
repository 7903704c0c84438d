"""Holography (Paper V), projected fringes (thesis 3.1) and phase-file I/O."""

import json

import numpy as np
import pytest

from shapeverify.phase import (depth_per_fringe, fringe_images, phase_difference, phase_shift,
                               phase_to_depth, phase_to_points, plot_unwrap, points_to_phase,
                               read_mask, read_phase, synthetic_wavelength, temporal_unwrap, unwrap,
                               unwrap_file, wrap)

TWO_PI = 2 * np.pi


# ------------------------------------------------------------------ holography

def test_synthetic_wavelength_and_depth_per_fringe():
    l1, l2 = 632.8e-6, 633.8e-6                     # mm
    lam = synthetic_wavelength(l1, l2)
    assert np.isclose(lam, l1 * l2 / 1e-6)
    assert synthetic_wavelength(l2, l1) == lam
    # 1 / Lambda = |1 / l1 - 1 / l2|
    assert np.isclose(1 / lam, abs(1 / l1 - 1 / l2))
    assert np.isclose(depth_per_fringe(lam), lam / 2)
    assert np.isclose(depth_per_fringe(lam, angle=np.pi / 3), lam / (2 * np.cos(np.pi / 6)))
    # the thesis' 0.20 mm per fringe needs Lambda = 0.4 mm
    assert np.isclose(depth_per_fringe(0.4), 0.2)
    for bad in ((1.0, 1.0), (0.0, 1.0), (-1.0, 2.0), (np.nan, 1.0)):
        with pytest.raises(ValueError):
            synthetic_wavelength(*bad)
    with pytest.raises(ValueError):
        depth_per_fringe(0.4, angle=np.pi)


def test_dual_wavelength_holograms_give_depth_through_unwrapping():
    rng = np.random.default_rng(0)
    l1, l2 = 632.8e-6, 633.8e-6
    lam = synthetic_wavelength(l1, l2)
    y, x = np.mgrid[0:80, 0:100].astype(float)
    z = 0.5 * np.exp(-((x - 50) ** 2 + (y - 40) ** 2) / 800.0) + 0.004 * x   # mm, up to ~3 fringes
    L = 2 * z                                                                # collimated, double pass
    speckle = rng.uniform(-np.pi, np.pi, z.shape)                            # common to both
    amp = rng.rayleigh(1.0, z.shape) + 0.05
    h1 = amp * np.exp(1j * (TWO_PI * L / l1 + speckle))
    h2 = amp * np.exp(1j * (TWO_PI * L / l2 + speckle + 0.7))
    psi = phase_difference(h1, h2)
    assert np.allclose(wrap(psi - (TWO_PI * L / lam - 0.7)), 0, atol=1e-6)
    depth = phase_to_depth(unwrap(psi), lam)
    d = depth - z
    assert np.allclose(d, d.mean(), atol=1e-7)           # exact up to the unknown offset
    # a zero hologram pixel -> NaN, then masked by unwrap
    h1[3, 3] = 0
    assert np.isnan(phase_difference(h1, h2)[3, 3])
    assert np.isnan(unwrap(phase_difference(h1, h2))[3, 3])
    # averaging window: a linear phase is kept exactly (away from the border)
    lin = TWO_PI * (0.05 * x + 0.03 * y)
    psi3 = phase_difference(np.exp(1j * lin), np.ones_like(lin), window=3)
    assert np.allclose(wrap(psi3 - lin)[1:-1, 1:-1], 0, atol=1e-9)
    with pytest.raises(ValueError):
        phase_difference(h1, h2[:, :5])
    with pytest.raises(ValueError):
        phase_difference(h1, h2, window=2)


def pinhole_rays(h, w, f=400.0):
    y, x = np.mgrid[0:h, 0:w].astype(float)
    d = np.stack([(x - (w - 1) / 2) / f, (y - (h - 1) / 2) / f, np.ones_like(x)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def test_perspective_geometry_round_trip_and_circular_fringes():
    rng = np.random.default_rng(1)
    d = pinhole_rays(40, 50)
    # a plane parallel to the detector at 300 mm, source at the camera centre: circular fringes
    r = 300.0 / d[..., 2]
    X = r[..., None] * d
    phi = points_to_phase(X, 0.4)
    assert np.allclose(phi, phi[:, ::-1]) and np.allclose(phi, phi[::-1, :])   # symmetric
    assert np.allclose(phi, TWO_PI * 2 * r / 0.4)
    assert np.allclose(phase_to_points(phi, 0.4, d), X)
    # separate source and camera centre, random points on the rays, non-zero path offset
    C = np.array([1.0, -2.0, 0.5])
    S = np.array([25.0, 10.0, -5.0])
    rr = rng.uniform(200, 400, (40, 50))
    Xs = C + rr[..., None] * d
    phi = points_to_phase(Xs, 0.4, center=C, source=S, path_offset=500.0)
    back = phase_to_points(phi, 0.4, d, center=C, source=S, path_offset=500.0)
    assert np.allclose(back, Xs, atol=1e-9)
    # NaN phase -> NaN point; a path shorter than |C - S| -> NaN
    phi[0, 0] = np.nan
    phi[1, 1] = -TWO_PI * 500.0 / 0.4 * 1.01
    back = phase_to_points(phi, 0.4, d, center=C, source=S, path_offset=500.0)
    assert np.all(np.isnan(back[0, 0])) and np.all(np.isnan(back[1, 1]))
    with pytest.raises(ValueError):
        phase_to_points(phi, 0.4, d[:, :10], center=C)
    with pytest.raises(ValueError):
        phase_to_points(phi, 0.4, d, center=(0, 0))


def test_holographic_groove_unwrapped_with_cad_reference_to_exact_points():
    # Paper V in miniature: a plane at 300 mm with a 1 mm deep milled trace, 0.2 mm per fringe
    d = pinhole_rays(60, 80, f=200.0)
    h, w = d.shape[:2]
    cols = np.arange(w)[None, :] * np.ones((h, 1))
    depth = 300.0 + np.where((cols >= 30) & (cols < 50), 1.0, 0.0)        # groove 5 fringes deep
    X = (depth / d[..., 2])[..., None] * d
    lam = 0.4
    true_phi = points_to_phase(X, lam)
    psi = wrap(true_phi + 0.1 * np.random.default_rng(2).standard_normal(true_phi.shape))
    # the CAD-predicted phase: same part, nominal depth 0.98 mm, unknown path offset of 0.3 fringe
    Xc = ((300.0 + np.where((cols >= 30) & (cols < 50), 0.98, 0.0)) / d[..., 2])[..., None] * d
    ref = points_to_phase(Xc, lam) + 0.3 * TWO_PI
    phi = unwrap(psi, reference=ref)
    assert np.all(np.round((phi - true_phi) / TWO_PI) == 0)
    pts = phase_to_points(phi, lam, d)
    assert np.max(np.linalg.norm(pts - X, axis=-1)) < 0.05           # noise 0.1 rad ~ 3 um
    # without the reference the groove depth is wrong by whole fringes
    phi0 = unwrap(psi)
    k = np.round((phi0 - true_phi) / TWO_PI)
    assert len(np.unique(k)) > 1


# ------------------------------------------------------------------ projected fringes

@pytest.mark.parametrize("n", [3, 4, 5, 8])
def test_n_step_phase_shifting_exact(n):
    rng = np.random.default_rng(n)
    phi = rng.uniform(-np.pi, np.pi, (30, 40))
    A = rng.uniform(0.3, 0.7, phi.shape)
    B = rng.uniform(0.05, 0.3, phi.shape)
    res = phase_shift(fringe_images(phi, steps=n, background=A, modulation=B))
    assert np.allclose(wrap(res.phase - phi), 0, atol=1e-10)
    assert np.allclose(res.modulation, B) and np.allclose(res.background, A)
    assert "PhaseShift(" in repr(res)


def test_phase_shifting_with_unequal_shifts_and_bad_input():
    rng = np.random.default_rng(9)
    phi = rng.uniform(-np.pi, np.pi, (10, 12))
    shifts = np.array([0.0, 1.1, 2.5, 4.0])
    res = phase_shift(fringe_images(phi, background=0.4, modulation=0.2, shifts=shifts), shifts=shifts)
    assert np.allclose(wrap(res.phase - phi), 0, atol=1e-10)
    with pytest.raises(ValueError, match="at least 3"):
        phase_shift(np.zeros((2, 4, 4)))
    with pytest.raises(ValueError, match="stack"):
        phase_shift(np.zeros((4, 4)))
    with pytest.raises(ValueError, match="determine"):
        phase_shift(np.zeros((3, 4, 4)), shifts=[0.0, np.pi, 2 * np.pi])
    with pytest.raises(ValueError, match="shifts"):
        phase_shift(np.zeros((3, 4, 4)), shifts=[0.0, 1.0])
    bad = np.zeros((3, 4, 4))
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        phase_shift(bad)


def test_temporal_unwrapping_exact_with_noise_and_discontinuities():
    rng = np.random.default_rng(3)
    y, x = np.mgrid[0:50, 0:200].astype(float)
    # an absolute phase within one period at f = 1, with a jump (a shadow edge) and curvature
    theta = 2.0 * (x / 100.0 - 1.0) + 0.2 * np.sin(y / 9.0) + 0.6 * (x > 120)   # in [-2.2, 2.8]
    freqs = [1, 6, 36, 216]
    psis = [wrap(f * theta + 0.08 * rng.standard_normal(theta.shape)) for f in freqs]
    phi = temporal_unwrap(psis, freqs)
    k = np.round((phi - freqs[-1] * theta) / TWO_PI)
    assert np.all(k == 0)
    assert np.allclose(wrap(phi - psis[-1]), 0, atol=1e-9)
    with pytest.raises(ValueError, match="increasing"):
        temporal_unwrap(psis[:2], [6, 1])
    with pytest.raises(ValueError, match="one frequency"):
        temporal_unwrap(psis, [1, 2])
    with pytest.raises(ValueError, match="K >= 2"):
        temporal_unwrap(psis[:1], [1])


# ------------------------------------------------------------------ files

def test_read_phase_scale_conventions(tmp_path):
    from PIL import Image
    v8 = np.arange(256, dtype=np.uint8).reshape(16, 16)
    Image.fromarray(v8).save(tmp_path / "p8.png")
    assert np.allclose(read_phase(tmp_path / "p8.png"), TWO_PI * v8 / 256 - np.pi)
    v16 = (np.arange(16 * 16, dtype=np.uint16) * 251).reshape(16, 16)
    Image.fromarray(v16).save(tmp_path / "p16.png")
    Image.fromarray(v16).save(tmp_path / "p16.tif")
    for name in ("p16.png", "p16.tif"):
        assert np.allclose(read_phase(tmp_path / name), TWO_PI * v16 / 65536 - np.pi)
    f = np.random.default_rng(0).uniform(-np.pi, np.pi, (7, 9)).astype(np.float32)
    Image.fromarray(f).save(tmp_path / "f.tif")
    assert np.array_equal(read_phase(tmp_path / "f.tif"), f.astype(np.float64))
    np.save(tmp_path / "f.npy", f.astype(np.float64) + 10)
    assert np.allclose(read_phase(tmp_path / "f.npy"), f + 10)
    np.save(tmp_path / "u8.npy", v8)
    assert np.allclose(read_phase(tmp_path / "u8.npy"), TWO_PI * v8 / 256 - np.pi)
    rgb = np.repeat(v8[..., None], 3, axis=2)
    Image.fromarray(rgb).save(tmp_path / "grey_rgb.png")
    assert np.allclose(read_phase(tmp_path / "grey_rgb.png"), TWO_PI * v8 / 256 - np.pi)


def test_read_phase_refuses_what_it_cannot_scale(tmp_path):
    from PIL import Image
    rgb = np.zeros((8, 8, 3), np.uint8)
    rgb[..., 0] = 200
    Image.fromarray(rgb).save(tmp_path / "colour.png")
    np.save(tmp_path / "i32.npy", np.zeros((4, 4), np.int32))
    np.save(tmp_path / "cube.npy", np.zeros((2, 4, 4)))
    frames = [Image.fromarray(np.zeros((4, 4), np.uint8)) for _ in range(2)]
    frames[0].save(tmp_path / "stack.tif", save_all=True, append_images=frames[1:])
    (tmp_path / "x.txt").write_text("1 2\n3 4\n")
    for name, msg in [("colour.png", "colour"), ("i32.npy", "no defined phase scale"),
                      ("cube.npy", "2-D"), ("stack.tif", "pages"), ("x.txt", "unsupported"),
                      ("missing.npy", "no such file")]:
        with pytest.raises(ValueError, match=msg):
            read_phase(tmp_path / name)


def test_unwrap_file_with_mask_and_plot(tmp_path):
    from PIL import Image
    y, x = np.mgrid[0:64, 0:96].astype(float)
    true = 0.004 * (x - 50) ** 2 + 0.1 * y
    v = np.floor((wrap(true, convention="modulo") + np.pi) / TWO_PI * 65536).astype(np.uint16)
    Image.fromarray(v).save(tmp_path / "in.png")
    mask = np.ones(true.shape, np.uint8) * 255
    mask[:, :10] = 0
    Image.fromarray(mask).save(tmp_path / "mask.png")
    assert np.array_equal(read_mask(tmp_path / "mask.png"), mask > 0)
    summary = unwrap_file(tmp_path / "in.png", tmp_path / "out.npy", method="auto",
                          mask_path=tmp_path / "mask.png", plot_path=tmp_path / "plot.png")
    json.dumps(summary)
    phi = np.load(tmp_path / "out.npy")
    assert np.all(np.isnan(phi[:, :10]))
    d = (phi - true)[:, 10:]
    assert np.allclose(d - d[0, 0], 0, atol=TWO_PI / 65536 * 1.01)      # quantisation only
    assert summary["valid_pixels"] == 64 * 86 and summary["masked_pixels"] == 64 * 10
    assert summary["shape"] == [64, 96] and summary["residues"] == 0
    assert (tmp_path / "plot.png").stat().st_size > 1000
    with pytest.raises(ValueError, match=r"\.npy"):
        unwrap_file(tmp_path / "in.png", tmp_path / "out.png")
    with pytest.raises(ValueError, match="mask"):
        np.save(tmp_path / "small.npy", np.ones((3, 3), bool))
        unwrap_file(tmp_path / "in.png", tmp_path / "o.npy", mask_path=tmp_path / "small.npy")
    with pytest.raises(ValueError):
        plot_unwrap(np.zeros((3, 3)), np.zeros((4, 4)), tmp_path / "p.png")
