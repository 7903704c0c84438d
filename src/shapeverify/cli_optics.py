"""Command-line front end of the optical chain: ``shapeverify measure`` and ``shapeverify calibrate``.

Registered on the main typer app by :func:`register_commands` (called at the end of ``cli.py``).
The commands only read files, call :func:`shapeverify.camera.measure` /
:func:`shapeverify.camera.calibrate`, and report on the terminal (progress on stderr).
"""

from __future__ import annotations

import json
from pathlib import Path

import typer

# numpy is imported where it is used: `shapeverify info` of a new CAD file starts its importer
# only after this module is imported, so every import here delays the answer

__all__ = ["register_commands", "read_image", "read_pose"]


def read_image(path: Path, expected_size=None, what: str = "image") -> np.ndarray:
    """A single-channel image (uint8 or uint16 as stored) from PNG/TIFF/... via ``cv2.imread``.

    The size its header declares is checked first (``expected_size``, a camera's
    ``(width, height)``, and :data:`shapeverify.io.image_header.MAX_IMAGE_PIXELS`): a small file
    that decodes to gigabytes is refused before it is decoded.
    """
    import cv2
    import numpy as np

    from shapeverify.io.image_header import check_image_size

    if not Path(path).exists():
        raise FileNotFoundError(2, "no such file", str(path))
    if Path(path).is_dir():
        raise IsADirectoryError(21, "Is a directory", str(path))
    check_image_size(path, expected_size, what=what)
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"{path}: not an image OpenCV can read (PNG or TIFF, 8 or 16 bit)")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
    if img.dtype not in (np.uint8, np.uint16):
        img = img.astype(np.float64)
    return img


def read_pose(path: Path) -> np.ndarray:
    """A 4 x 4 pose (model -> left camera) from .json (nested list or {"T_left_model": ...}), .npy or text."""
    import numpy as np

    path = Path(path)
    if path.suffix.lower() == ".json":
        data = json.loads(path.read_text())
        if isinstance(data, dict):
            data = data.get("T_left_model", data.get("T"))
        T = np.asarray(data, dtype=np.float64)
    elif path.suffix.lower() == ".npy":
        from shapeverify.io.npy import load_npy

        T = load_npy(path, error=ValueError)   # no pickle, header checked against the file
    else:
        T = np.loadtxt(path)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"{path}: the pose must be a finite 4 x 4 matrix (model -> left camera), got shape {T.shape}")
    return T


def _split_pairs(images):
    left = sorted(p for p in images if "left" in p.name.lower())
    right = sorted(p for p in images if "right" in p.name.lower())
    other = [p for p in images if p not in left and p not in right]
    if other or not left or len(left) != len(right):
        raise ValueError("calibration images must be pairs named with 'left' and 'right' (e.g. left_01.png, "
                         f"right_01.png); got {len(left)} left, {len(right)} right, {len(other)} other "
                         f"({', '.join(p.name for p in other[:3])})")
    return left, right


def register_commands(app: typer.Typer) -> None:
    """Add ``measure`` and ``calibrate`` to ``app``."""
    from shapeverify import cli_common as _cli

    @app.command()
    def measure(
        rig: Path = typer.Argument(..., help="rig.json / rig.yaml (cameras + projector, OpenCV conventions, mm)"),
        left: Path = typer.Argument(..., help="left camera fringe image (PNG/TIFF, 8 or 16 bit)"),
        right: Path = typer.Argument(..., help="right camera fringe image"),
        output: Path = typer.Option(..., "-o", "--output", help="scan file to write (.ply, with a quality field)"),
        model: Path = typer.Option(None, "--model", help="CAD model or .svm: predicts the fringe order"),
        pose: Path = typer.Option(None, "--pose", help="4x4 model->left-camera pose (.json/.npy/.txt); "
                                                        "default identity (model given in the rig frame)"),
        method: str = typer.Option("ftp", "--method", help="phase analysis: ftp (fast) or wff (windowed Fourier)"),
        depth_range: str = typer.Option(None, "--depth-range", help="ZNEAR,ZFAR in mm (left camera z)"),
        min_quality: float = typer.Option(0.0, "--min-quality", help="drop points below this quality (0..1)"),
    ):
        """Measure 3-D points from one fringe image per camera (stereo phase matching)."""
        from shapeverify.camera.rig import load_rig
        from shapeverify.camera.stereo import StereoMatching, measure as _measure
        from shapeverify.io.points import write_ply

        import numpy as np

        _cli.require_files(rig, left, right, *([model] if model else []), *([pose] if pose else []))
        with _cli.stage("reading rig and images"):
            r = _cli.guard(load_rig, rig)
            L = _cli.guard(read_image, left, r.left.size, "left image")
            R = _cli.guard(read_image, right, r.right.size, "right image")
        dr = None
        if depth_range:
            try:
                dr = tuple(float(x) for x in depth_range.split(","))
                assert len(dr) == 2
            except (ValueError, AssertionError):
                _cli.fail(f"--depth-range must be ZNEAR,ZFAR in mm, got {depth_range!r}")
        prep = T = None
        if model is not None:
            import shapeverify as sv
            with _cli.stage("loading model"):
                prep = _cli.guard(sv.load_prepared if model.suffix.lower() == ".svm" else sv.load_model, model)
            T = _cli.guard(read_pose, pose) if pose else np.eye(4)
        with _cli.stage("phase, fringe orders, triangulation"):
            scan = _cli.guard(_measure, r, L, R, model=prep, T_left_model=T, method=method,
                              matching=StereoMatching(depth_range=dr))
        keep = scan.quality >= min_quality
        if not keep.any():
            _cli.fail(f"no point measured (usable left pixels: {scan.info.get('usable_left', 0)}); check the rig "
                       "and the images (fringe contrast, exposure)")
        with _cli.stage(f"writing {output}"):
            _cli.guard(write_ply, output, scan.points[keep], scalars={"quality": scan.quality[keep]})
        t = ", ".join(f"{k} {v:.2f} s" for k, v in scan.timings.items())
        _cli.out.print(f"{int(keep.sum()):,} points (of {scan.info['usable_left']:,} usable left pixels), "
                       f"median quality {float(np.median(scan.quality[keep])):.3f}; {t}; frame: left camera, mm")

    @app.command()
    def calibrate(
        images: list[Path] = typer.Argument(..., help="chessboard image pairs, names containing 'left' / 'right'"),
        output: Path = typer.Option(..., "-o", "--output", help="rig file to write (.json or .yaml)"),
        pattern: str = typer.Option("9x6", "--pattern", help="inner corners per row x per column, e.g. 9x6"),
        square: float = typer.Option(10.0, "--square", help="square side in mm"),
        projector: Path = typer.Option(None, "--projector", help="rig file whose projector block is copied"),
        fix_k3: bool = typer.Option(False, "--fix-k3", help="keep the k3 distortion coefficient at 0"),
    ):
        """Calibrate the stereo cameras from chessboard image pairs (OpenCV); prints the reprojection error."""
        from shapeverify.camera.calibration import calibrate as _calibrate
        from shapeverify.camera.rig import load_rig, save_rig

        _cli.require_files(*images, *([projector] if projector else []))
        try:
            pat = tuple(int(x) for x in pattern.lower().split("x"))
            assert len(pat) == 2 and min(pat) >= 2
        except (ValueError, AssertionError):
            _cli.fail(f"--pattern must be COLSxROWS inner corners (e.g. 9x6), got {pattern!r}")
        lefts, rights = _cli.guard(_split_pairs, list(images))
        proj = pat_f = None
        if projector is not None:
            base = _cli.guard(load_rig, projector)
            proj, pat_f = base.projector, base.pattern
        with _cli.stage(f"finding corners and calibrating ({len(lefts)} pairs)"):
            L = [_cli.guard(read_image, p) for p in lefts]
            R = [_cli.guard(read_image, p) for p in rights]
            cal = _cli.guard(_calibrate, L, R, pattern=pat, square_mm=square, projector=proj,
                              pattern_fringe=pat_f, fix_k3=fix_k3)
        _cli.guard(save_rig, cal.rig, output)
        skipped = f"; board not found in pair(s) {list(cal.rejected)}" if cal.rejected else ""
        _cli.out.print(f"reprojection error (RMS): left {cal.rms_left:.4f} px, right {cal.rms_right:.4f} px, "
                       f"stereo {cal.rms_stereo:.4f} px over {cal.views} pairs{skipped}; wrote {output}"
                       + ("" if proj is not None else " (no projector: add one with --projector to measure)"))
