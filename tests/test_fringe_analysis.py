"""Single-image fringe analysis (FTP, WFF) against known phases and the fringe simulator's truth."""

import numpy as np
import pytest

from shapeverify.phase.fringe_analysis import ftp, wff


def _wrapped_err(a, b):
    return np.angle(np.exp(1j * (a - b)))


def _pattern(H=192, W=224, period=7.5, noise=1.0, B=80.0, A=100.0, seed=0):
    v, u = np.mgrid[0:H, 0:W].astype(float)
    phi = 2 * np.pi * (u / period + v / 60.0) + 3e-4 * (u - W / 2) ** 2 - 2e-4 * (v - H / 2) ** 2
    img = A + B * np.cos(phi) + np.random.default_rng(seed).normal(0, noise, phi.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8), phi


@pytest.mark.slow  # over 4 s of CPU: out of `make test-fast` (issue 32)
def test_ftp_recovers_a_chirped_carrier_phase_up_to_the_image_border():
    img, phi = _pattern()
    r = ftp(img)
    err = _wrapped_err(r.phase, phi)
    assert r.mask[3:-3, 3:-3].mean() > 0.99
    inner = err[12:-12, 12:-12]
    assert np.sqrt(np.mean(inner ** 2)) < 0.01 and np.abs(inner).max() < 0.04
    assert np.abs(err[4:-4, 4:-4]).max() < 0.1  # the edge-corrected border band included
    assert np.nanmax(np.abs(err)) < 0.25
    assert abs(1 / np.hypot(*r.carrier) - 7.5) < 0.3


def test_ftp_phase_sign_follows_direction():
    img, phi = _pattern()
    a = ftp(img, direction=(1, 0))
    b = ftp(img, direction=(-1, 0))
    np.testing.assert_allclose(_wrapped_err(b.phase, -a.phase)[a.mask], 0.0, atol=1e-9)
    assert a.carrier[0] > 0 > b.carrier[0]


def test_edge_correction_reduces_the_truncated_window_bias():
    img, phi = _pattern(noise=0.0)
    v, u = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    mask = (u - 110.0) ** 2 + (v - 95.0) ** 2 < 70.0 ** 2
    band = mask & ((u - 110.0) ** 2 + (v - 95.0) ** 2 > 62.0 ** 2)
    on = ftp(img, mask=mask)
    off = ftp(img, mask=mask, edge_correction=False)
    e_on = _wrapped_err(on.phase, phi)[band & on.mask]
    e_off = _wrapped_err(off.phase, phi)[band & off.mask]
    assert np.sqrt(np.mean(e_on ** 2)) < 0.65 * np.sqrt(np.mean(e_off ** 2))
    assert not on.mask[~mask].any()


def test_masks_flag_saturation_shadow_and_low_modulation():
    img, phi = _pattern()
    f = img.astype(float)
    f[20:60, 20:60] = 255.0  # a saturated spot
    f[120:170, 10:70] = np.random.default_rng(1).normal(2.0, 1.0, (50, 60))  # shadow (dark, noise)
    v, u = np.mgrid[0:f.shape[0], 0:f.shape[1]]
    low = (u > 150) & (v > 120)
    f[low] = 100 + 3 * np.cos(phi[low])  # lit but almost no fringe contrast
    r = ftp(np.clip(np.round(f), 0, 255).astype(np.uint8))
    assert r.saturated[20:60, 20:60].all() and r.saturated[17, 40] and not r.mask[20:60, 20:60].any()
    assert r.shadow[125:165, 15:65].all() and not r.mask[125:165, 15:65].any()
    assert r.low_modulation[130:, 160:].mean() > 0.95 and not r.mask[130:, 160:].any()
    ok = r.mask[75:110, 80:140]
    assert ok.all()
    assert np.abs(_wrapped_err(r.phase, phi)[75:110, 80:140]).max() < 0.05


def test_sixteen_bit_images_give_the_eight_bit_phase():
    img, _ = _pattern()
    a = ftp(img)
    b = ftp(img.astype(np.uint16) * 257)
    np.testing.assert_allclose(_wrapped_err(a.phase, b.phase)[a.mask], 0.0, atol=1e-5)


def test_wff_filters_noise_better_than_the_noisy_input_and_matches_the_phase():
    img, phi = _pattern(H=128, W=128, noise=12.0, B=40.0)
    r = wff(img)
    err = _wrapped_err(r.phase, phi)[12:-12, 12:-12]
    assert np.sqrt(np.nanmean(err ** 2)) < 0.04
    f = ftp(img)
    ef = _wrapped_err(f.phase, phi)[12:-12, 12:-12]
    assert np.sqrt(np.nanmean(err ** 2)) < 1.2 * np.sqrt(np.nanmean(ef ** 2))


@pytest.mark.parametrize("bad, match", [
    (np.zeros(100), "2-D array"),
    (np.full((32, 32), np.nan), "NaN or inf"),
])
def test_bad_images_are_rejected(bad, match):
    with pytest.raises(ValueError, match=match):
        ftp(bad)


def test_bad_arguments_are_rejected():
    img, _ = _pattern(H=32, W=32)
    with pytest.raises(ValueError, match="mask must have the image's shape"):
        ftp(img, mask=np.ones((10, 10), bool))
    with pytest.raises(ValueError, match="carrier must be"):
        ftp(img, carrier=(0.0, 0.0))
    with pytest.raises(ValueError, match="direction must be"):
        ftp(img, direction=(0, 0))


def test_ftp_phase_of_simulated_fringes_matches_the_projector_phase_at_the_true_points():
    from shapeverify.camera.stereo import phase_direction
    from shapeverify.simulate.fringes import demo_scene, fringe_images

    model, rig, T = demo_scene(96, 96)
    f = fringe_images(model, rig, T, period_mm=1.0, noise=1.0)
    for cam in ("left", "right"):
        img = getattr(f, cam)
        r = ftp(img, direction=phase_direction(f.rig, cam))
        pts = f.truth[cam]["points"].reshape(-1, 3)
        uv, _ = f.rig.projector.project(np.nan_to_num(pts))
        true = (2 * np.pi * uv[:, 0] / f.rig.pattern.period_px).reshape(img.shape)
        ok = r.mask & f.truth[cam]["lit"]
        assert ok.mean() > 0.9
        err = _wrapped_err(r.phase, true)[ok]
        assert np.sqrt(np.mean(err ** 2)) < 0.03 and np.abs(err).max() < 0.2
