"""The rig file format (OpenCV conventions), its projection model, and chessboard calibration."""

import json
import re

import numpy as np
import pytest

cv2 = pytest.importorskip("cv2")

from shapeverify.camera.calibration import board_points, calibrate, find_corners, render_chessboard  # noqa: E402
from shapeverify.camera.rig import Device, Rig, RigFormatError, load_rig, look_at_rig, save_rig  # noqa: E402

ISSUE_RIG = """
{"units": "mm",
 "cameras": {"left":  {"K": [[2000,0,319.5],[0,2000,239.5],[0,0,1]], "dist": [0,0,0,0,0], "size": [640,480],
                       "R": [[1,0,0],[0,1,0],[0,0,1]], "T": [0,0,0]},
             "right": {"K": [[2010,0,320],[0,2010,240],[0,0,1]], "dist": [-0.1,0.05,0.001,-0.002,0.01],
                       "size": [640,480], "R": [[0.9396926,0,-0.3420201],[0,1,0],[0.3420201,0,0.9396926]],
                       "T": [-200,0,30]}},
 "projector": {"K": [[1500,0,639.5],[0,1500,399.5],[0,0,1]], "dist": [0,0,0,0,0], "size": [1280,800],
               "R": [[0.9848078,0,-0.1736482],[0,1,0],[0.1736482,0,0.9848078]], "T": [-100,0,10],
               "pattern": {"type": "sinusoid", "direction": "columns", "period_px": 9.0}}}
"""


def test_rig_json_in_the_issue_form_is_read_exactly(tmp_path):
    p = tmp_path / "rig.json"
    p.write_text(ISSUE_RIG)
    rig = load_rig(p)
    assert rig.left.size == (640, 480) and rig.right.K[0, 0] == 2010
    np.testing.assert_array_equal(rig.right.dist, [-0.1, 0.05, 0.001, -0.002, 0.01])
    np.testing.assert_array_equal(rig.right.T, [-200, 0, 30])
    assert rig.pattern.period_px == 9.0 and rig.pattern.direction == "columns"
    # right camera centre = -R^T T (x_device = R x_left + T)
    np.testing.assert_allclose(rig.right.center, -rig.right.R.T @ rig.right.T)


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_rig_round_trip_json_and_yaml_is_lossless(tmp_path, suffix):
    rig, _ = look_at_rig((0, 0, 0), 300.0, dist=(-0.05, 0.01, 1e-3, -2e-3, 0.002))
    p = save_rig(rig, tmp_path / f"rig{suffix}")
    back = load_rig(p)
    assert back.to_dict() == rig.to_dict()
    if suffix == ".json":
        assert set(json.loads(p.read_text())) == {"units", "cameras", "projector"}


@pytest.mark.parametrize("edit, key", [
    (lambda d: d["cameras"]["right"].pop("K"), "cameras.right is missing key(s) K"),
    (lambda d: d["cameras"]["right"].__setitem__("R", [[1, 0], [0, 1]]), "cameras.right.R must have shape [3, 3]"),
    (lambda d: d.__setitem__("units", "m"), "units must be \"mm\""),
    (lambda d: d["cameras"]["left"].__setitem__("T", [1, 0, 0]), "cameras.left must have R = identity"),
    (lambda d: d["projector"]["pattern"].__setitem__("period_px", 0.5), "projector.pattern.period_px"),
    (lambda d: d["projector"]["pattern"].__setitem__("direction", "diagonal"), "projector.pattern.direction"),
    (lambda d: d["cameras"]["right"].__setitem__("dist", [0, 0, 0]), "cameras.right.dist must have shape [5]"),
    (lambda d: d["projector"].__setitem__("size", [12.5, 8]), "projector.size must be [width, height]"),
])
def test_bad_rig_file_names_the_key(tmp_path, edit, key):
    d = json.loads(ISSUE_RIG)
    edit(d)
    p = tmp_path / "rig.json"
    p.write_text(json.dumps(d))
    with pytest.raises(RigFormatError, match=re.escape(key)):
        load_rig(p)


def test_opencv_style_vectors_and_short_dist_are_accepted(tmp_path):
    d = json.loads(ISSUE_RIG)
    d.pop("units")
    d["cameras"]["right"]["T"] = [[-200], [0], [30]]
    d["cameras"]["right"]["dist"] = [-0.1, 0.05, 0.001, -0.002, 0.01, 0, 0, 0]
    d["projector"]["dist"] = [0, 0, 0, 0]
    rig = Rig.from_dict(d)
    np.testing.assert_array_equal(rig.right.T, [-200, 0, 30])
    np.testing.assert_array_equal(rig.right.dist, [-0.1, 0.05, 0.001, -0.002, 0.01])
    assert rig.projector.dist.shape == (5,)
    d["cameras"]["right"]["dist"] = [-0.1, 0.05, 0.001, -0.002, 0.01, 0.3, 0, 0]
    with pytest.raises(RigFormatError, match="rational / thin-prism"):
        Rig.from_dict(d)


def test_not_json_is_a_clear_error(tmp_path):
    p = tmp_path / "rig.json"
    p.write_text("{units: mm")
    with pytest.raises(RigFormatError, match="not valid JSON"):
        load_rig(p)


def test_projection_matches_opencv_projectPoints_with_full_distortion():
    rig = Rig.from_dict(json.loads(ISSUE_RIG))
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-40, 40, 200), rng.uniform(-30, 30, 200), rng.uniform(250, 400, 200)])
    for dev in (rig.left, rig.right, rig.projector):
        uv, _ = dev.project(X)
        rvec, _ = cv2.Rodrigues(dev.R)
        ref, _ = cv2.projectPoints(X, rvec, dev.T, dev.K, dev.dist)
        np.testing.assert_allclose(uv, ref.reshape(-1, 2), rtol=0, atol=1e-4)  # R given to 7 digits; Rodrigues re-orthonormalises


def test_pixel_rays_pass_through_the_projected_point():
    rig = Rig.from_dict(json.loads(ISSUE_RIG))
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(-40, 40, 100), rng.uniform(-30, 30, 100), rng.uniform(250, 400, 100)])
    uv, _ = rig.right.project(X)
    o, d = rig.right.rays(uv)
    # distance of X from the ray o + t d
    v = X - o
    off = v - (v * d).sum(axis=1, keepdims=True) * d
    assert np.abs(off).max() < 1e-9


def _board_poses(rng, n, sq, pattern, centre_z=400.0):
    from scipy.spatial.transform import Rotation

    poses = []
    for _ in range(n):
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(rng.uniform(-0.45, 0.45, 3)).as_matrix()
        c = np.array([-40 + rng.uniform(-35, 35), rng.uniform(-30, 30), centre_z + rng.uniform(-50, 50)])
        T[:3, 3] = c - T[:3, :3] @ np.array([(pattern[0] - 1) * sq / 2, (pattern[1] - 1) * sq / 2, 0])
        poses.append(T)
    return poses


def test_chessboard_corners_are_found_where_the_exact_projection_puts_them():
    dev = Device([[500, 0, 159.5], [0, 500, 119.5], [0, 0, 1]], [0] * 5, (320, 240))
    T = np.eye(4)
    T[:3, 3] = [-60 + 3.3, -37.5 + 1.7, 400]
    img = render_chessboard(dev, T, (9, 6), 15.0, supersample=3)
    c = find_corners(img, (9, 6))
    uv, _ = dev.project(board_points((9, 6), 15.0).astype(float) @ T[:3, :3].T + T[:3, 3])
    assert c is not None and np.abs(c - uv).max() < 0.25


@pytest.mark.slow
def test_calibration_from_simulated_chessboards_recovers_the_rig():
    rig, _ = look_at_rig((0, 0, 0), 400.0, width=480, height=360, fov_deg=40, dist=(-0.05, 0.02, 0, 0, 0))
    pattern, sq = (9, 6), 15.0
    poses = _board_poses(np.random.default_rng(1), 12, sq, pattern)
    L = render_chessboard(rig.left, poses, pattern, sq, supersample=4)
    R = render_chessboard(rig.right, poses, pattern, sq, supersample=4)
    cal = calibrate(L, R, pattern, sq, fix_k3=True)
    assert cal.views >= 10
    assert max(cal.rms_left, cal.rms_right, cal.rms_stereo) < 0.1  # the issue's target (pixels)
    got, true = cal.rig, rig
    np.testing.assert_allclose(np.diag(got.left.K)[:2], np.diag(true.left.K)[:2], rtol=5e-3)
    np.testing.assert_allclose(np.diag(got.right.K)[:2], np.diag(true.right.K)[:2], rtol=5e-3)
    np.testing.assert_allclose(got.left.dist[:2], true.left.dist[:2], atol=0.03)
    ang = np.degrees(np.arccos(np.clip((np.trace(got.right.R @ true.right.R.T) - 1) / 2, -1, 1)))
    assert ang < 0.3
    assert abs(np.linalg.norm(got.right.T) - np.linalg.norm(true.right.T)) < 0.01 * np.linalg.norm(true.right.T)
    # what matters downstream: 3-D points triangulated with the calibrated rig
    X = np.array([[-30.0, 10.0, 390.0], [0.0, -20.0, 420.0], [25.0, 15.0, 380.0]])
    ul, _ = true.left.project(X)
    ur, _ = true.right.project(X)
    P1 = got.left.K @ np.hstack([np.eye(3), np.zeros((3, 1))])
    P2 = got.right.K @ np.hstack([got.right.R, got.right.T[:, None]])
    nl = cv2.undistortPoints(ul.reshape(-1, 1, 2), got.left.K, got.left.dist, P=got.left.K).reshape(-1, 2)
    nr = cv2.undistortPoints(ur.reshape(-1, 1, 2), got.right.K, got.right.dist, P=got.right.K).reshape(-1, 2)
    Xh = cv2.triangulatePoints(P1, P2, nl.T, nr.T)
    Xc = (Xh[:3] / Xh[3]).T
    assert np.abs(Xc - X).max() < 1.0  # mm at 400 mm


def test_calibration_needs_three_boards():
    dev = Device([[500, 0, 159.5], [0, 500, 119.5], [0, 0, 1]], [0] * 5, (320, 240))
    blank = np.full((240, 320), 128, np.uint8)
    with pytest.raises(ValueError, match="found in only 0 image pair"):
        calibrate([blank] * 3, [blank] * 3, (9, 6), 15.0)
    with pytest.raises(ValueError, match="as many left as right"):
        calibrate([blank] * 3, [blank] * 2)
    assert dev.width == 320


def test_cli_calibrate_writes_a_rig_and_prints_the_reprojection_error(tmp_path):
    from typer.testing import CliRunner

    from shapeverify.cli import app

    rig, _ = look_at_rig((0, 0, 0), 400.0, width=320, height=240, fov_deg=40)
    pattern, sq = (7, 5), 18.0
    poses = _board_poses(np.random.default_rng(3), 5, sq, pattern)
    paths = []
    for i, (a, b) in enumerate(zip(render_chessboard(rig.left, poses, pattern, sq, supersample=2),
                                   render_chessboard(rig.right, poses, pattern, sq, supersample=2))):
        for name, img in (("left", a), ("right", b)):
            p = tmp_path / f"{name}_{i:02d}.png"
            cv2.imwrite(str(p), img)
            paths.append(str(p))
    proj = save_rig(rig, tmp_path / "base.json")
    out = tmp_path / "rig.yaml"
    res = CliRunner().invoke(app, ["calibrate", *paths, "-o", str(out), "--pattern", "7x5", "--square", "18",
                                   "--projector", str(proj), "--fix-k3"])
    assert res.exit_code == 0, res.output
    assert "reprojection error (RMS)" in res.output
    got = load_rig(out)
    assert got.projector is not None and got.pattern.period_px == rig.pattern.period_px
    np.testing.assert_allclose(got.left.K[0, 0], rig.left.K[0, 0], rtol=0.01)
    bad = CliRunner().invoke(app, ["calibrate", *paths[:2], str(proj), "-o", str(out)])
    assert bad.exit_code == 2 and "named with 'left' and 'right'" in bad.output
