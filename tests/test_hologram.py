"""Off-axis holograms (issue 15 item 5): reconstruction, propagation, the Paper V groove."""

import numpy as np
import pytest
from scipy import ndimage

from shapeverify.phase import depth_per_fringe, synthetic_wavelength
from shapeverify.phase.hologram import (angular_spectrum, dual_wavelength_depth, find_carrier,
                                        reconstruct)
from shapeverify.phase.hologram import Reconstruction
from shapeverify.simulate.hologram import (dual_wavelength_holograms, grooved_plate,
                                           rough_surface, simulate_hologram)
from shapeverify.simulate.hologram import OffAxis

L1 = 632.8e-6                        # mm
LAM = 0.4                            # synthetic wavelength: 0.2 mm depth per fringe
L2 = L1 * LAM / (LAM - L1)
PITCH = 0.05


def test_paper_v_wavelengths_give_0_2_mm_per_fringe():
    assert synthetic_wavelength(L1, L2) == pytest.approx(LAM)
    assert depth_per_fringe(synthetic_wavelength(L1, L2)) == pytest.approx(0.2)


def test_carrier_filtering_recovers_the_object_wave_exactly():
    depth, _ = grooved_plate((128, 160), PITCH, 2.0, 0.3)
    # a carrier on the FFT grid (44/160, -28/128 cycles/pixel): the filtering is exact
    cx, cy = 44 / 160, -28 / 128
    h = simulate_hologram(depth, L1, heights=rough_surface(depth.shape, 1e-3, rng=4),
                          off_axis=OffAxis(carrier=(cx, cy), aperture=0.09))
    o = reconstruct(h.intensity, carrier=h.carrier)
    assert np.allclose(o, h.field, atol=1e-9)
    c = find_carrier(h.intensity)
    assert np.hypot(c[0] - cx, c[1] - cy) < 0.005
    # the twin image (the other half-plane) is the conjugate wave
    twin = reconstruct(h.intensity, carrier=(-cx, -cy))
    assert np.allclose(twin, np.conj(h.field), atol=1e-9)


def test_angular_spectrum_plane_wave_phase_and_round_trip():
    H, W = 64, 80
    y, x = np.mgrid[0:H, 0:W]
    fx = 5 / W                                                  # cycles/pixel, periodic
    u = np.exp(2j * np.pi * fx * x)
    d = 3.7
    out = angular_spectrum(u, d, L1, PITCH)
    kz = np.sqrt(1 / L1 ** 2 - (fx / PITCH) ** 2)
    assert np.allclose(out, u * np.exp(2j * np.pi * d * kz), atol=1e-9)
    rng = np.random.default_rng(0)
    v = rng.standard_normal((H, W)) + 1j * rng.standard_normal((H, W))
    assert np.allclose(angular_spectrum(angular_spectrum(v, 20.0, L1, PITCH), -20.0, L1, PITCH), v,
                       atol=1e-9)


def _groove_errors(res, depth, groove, margin=6):
    far = ndimage.binary_erosion(groove, iterations=margin) | ndimage.binary_erosion(~groove, iterations=margin)
    sel = far & np.isfinite(res.depth)
    e = res.depth - depth
    e = e - np.median(e[sel])
    floor = np.median(res.depth[ndimage.binary_erosion(groove, iterations=margin)])
    top = np.median(res.depth[ndimage.binary_erosion(~groove, iterations=margin)])
    return float(np.sqrt(np.mean(e[sel] ** 2))), floor - top, sel.mean()


@pytest.mark.parametrize("distance", [0.0, 25.0])
def test_milled_groove_of_paper_v_recovered_within_5_um(distance):
    # 1 mm deep groove = 5 synthetic fringes; speckle (1 um rough), 5 % camera noise, 8 bits
    depth, groove = grooved_plate((256, 256), PITCH, 3.0, 1.0, tilt=(0.004, -0.002))
    h1, h2 = dual_wavelength_holograms(depth, L1, L2, pixel_pitch=PITCH, noise=0.05, bits=8,
                                       distance=distance, rng=7)
    cad = grooved_plate((256, 256), PITCH, 3.0, 1.0)[0] + 0.03       # nominal, 30 um offset
    res = dual_wavelength_depth(h1.intensity, h2.intensity, L1, L2, reference_depth=cad,
                                reconstruction=Reconstruction(distance=distance,
                                                              pixel_pitch=PITCH))
    rms, groove_depth, covered = _groove_errors(res, depth, groove)
    assert rms < 5e-3                                                # mm
    assert abs(groove_depth - 1.0) < 5e-3
    assert covered > 0.75
    assert res.synthetic == pytest.approx(LAM)
    # data alone cannot count the five fringes of the groove wall
    alone = dual_wavelength_depth(h1.intensity, h2.intensity, L1, L2,
                                  reconstruction=Reconstruction(distance=distance,
                                                                pixel_pitch=PITCH))
    assert abs(_groove_errors(alone, depth, groove)[1] - 1.0) > 0.1


def test_background_without_surface_and_bad_input():
    depth, _ = grooved_plate((64, 64), PITCH, 1.0, 0.2)
    depth[:, :10] = np.nan
    h = simulate_hologram(depth, L1)
    assert np.all(np.isfinite(h.intensity))
    with pytest.raises(ValueError, match="overlap the orders"):
        simulate_hologram(depth, L1, off_axis=OffAxis(carrier=(0.1, 0.1), aperture=0.1))
    with pytest.raises(ValueError, match="NaN everywhere"):
        simulate_hologram(np.full((16, 16), np.nan), L1)
    with pytest.raises(ValueError, match="carrier must be"):
        reconstruct(h.intensity, carrier=(0.7, 0.0))
    with pytest.raises(ValueError, match="needs wavelength and pixel_pitch"):
        reconstruct(h.intensity, carrier=h.carrier, distance=5.0)
    with pytest.raises(ValueError, match="same shape"):
        dual_wavelength_depth(h.intensity, h.intensity[:-1], L1, L2)
    with pytest.raises(ValueError, match="finite"):
        reconstruct(np.full((16, 16), np.nan))


def test_cli_hologram_writes_the_depth_map(tmp_path):
    from typer.testing import CliRunner

    from shapeverify.cli import app

    depth, groove = grooved_plate((128, 128), PITCH, 2.0, 1.0)
    h1, h2 = dual_wavelength_holograms(depth, L1, L2, pixel_pitch=PITCH, noise=0.02, bits=12, rng=3)
    np.save(tmp_path / "h1.npy", h1.intensity.astype(np.uint16))
    np.save(tmp_path / "h2.npy", h2.intensity.astype(np.uint16))
    np.save(tmp_path / "cad.npy", depth)
    out = tmp_path / "depth.npy"
    res = CliRunner().invoke(app, ["hologram", str(tmp_path / "h1.npy"), str(tmp_path / "h2.npy"),
                                   "-o", str(out), "--lambda1", str(L1), "--lambda2", str(L2),
                                   "--reference", str(tmp_path / "cad.npy")])
    assert res.exit_code == 0, res.output
    assert "depth_per_fringe_mm: 0.2" in res.output
    got = np.load(out)
    inner = ndimage.binary_erosion(groove, iterations=6)
    outer = ndimage.binary_erosion(~groove, iterations=6)
    assert abs(np.nanmedian(got[inner]) - np.nanmedian(got[outer]) - 1.0) < 5e-3
    bad = CliRunner().invoke(app, ["hologram", str(tmp_path / "h1.npy"), str(tmp_path / "nope.npy"),
                                   "-o", str(out), "--lambda1", str(L1), "--lambda2", str(L2)])
    assert bad.exit_code == 2 and "no such file" in bad.output


@pytest.mark.slow
def test_hologram_of_a_cad_render_recovers_its_depth():
    # the chain from the CAD model: exact ray-NURBS depth render -> speckle holograms -> depth
    from shapeverify import prepare
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.camera import PinholeCamera
    from shapeverify.simulate.hologram import depth_from_model

    prep = prepare(wavy_panel(split=False), spacing=2.0)
    # a narrow view of the panel's saddle (x = 25 pi, y = 15 pi): slopes small enough that the
    # two wavelengths' speckle stays correlated (a steep slope decorrelates it)
    cam = PinholeCamera.look_at((78.54, 47.12, 150.0), (78.54, 47.12, 0.0), up=(0, 1, 0),
                                fov_deg=2.0, width=128, height=128)
    depth = depth_from_model(prep, cam)
    assert np.isfinite(depth).all() and 149.0 < np.nanmedian(depth) < 151.0
    h1, h2 = dual_wavelength_holograms(depth, L1, L2, pixel_pitch=0.04, noise=0.02, bits=12)
    res = dual_wavelength_depth(h1.intensity, h2.intensity, L1, L2, reference_depth=depth + 0.01)
    e = (res.depth - depth)[6:-6, 6:-6]
    e = e - np.median(e)
    assert np.sqrt(np.mean(e ** 2)) < 5e-3


@pytest.mark.slow
def test_holograms_feed_the_cad_regularised_predict_unwrap_register_loop():
    # Paper V's chain: holograms -> synthetic phase -> unwrap_with_cad (prediction from the exact
    # CAD render at an approximate pose, unwrapping, registration, again) -> points on the part
    import warnings

    from shapeverify import phase, prepare
    from shapeverify.cad.examples import wavy_panel
    from shapeverify.camera import PinholeCamera
    from shapeverify.phase.hologram import synthetic_phase
    from shapeverify.registration.rigid import make_transform, rodrigues
    from shapeverify.simulate.hologram import depth_from_model

    prep = prepare(wavy_panel(split=False), spacing=2.0)
    cam = PinholeCamera.look_at((78.54, 47.12, 150.0), (78.54, 47.12, 0.0), up=(0, 1, 0),
                                fov_deg=2.0, width=96, height=96)
    path = depth_from_model(prep, cam)                   # one-way path from the camera centre
    h1, h2 = dual_wavelength_holograms(path, L1, L2, pixel_pitch=0.05, noise=0.02, bits=12)
    psi, quality = synthetic_phase(h1.intensity, h2.intensity, L1, L2)
    assert np.median(quality) > 0.9
    setup = phase.HolographySetup(camera=cam, synthetic=LAM)
    T0 = make_transform(rodrigues(np.array([0.0, 0.0, 0.002])), np.array([0.15, -0.1, 0.03]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # a 5 mm patch leaves two rotations weakly determined
        res = phase.unwrap_with_cad(psi, prep, setup, T0)
    assert res.converged
    pts = phase.cad_unwrap.points_from_phase(res.phase, setup)
    assert len(pts) == path.size
    d = prep.closest(pts @ res.T_model_scan[:3, :3].T + res.T_model_scan[:3, 3]).distances
    assert np.sqrt(np.mean(d ** 2)) < 0.01                # mm: every pixel on the right fringe
