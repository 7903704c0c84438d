"""The optical demo: fringe images of the example panel, rendered and measured (``make demo``).

It lived in :mod:`shapeverify.camera.stereo`; it renders with :mod:`.fringes` and measures with
:func:`shapeverify.camera.measure`, so it belongs to the simulation, which uses the camera
package (the camera package importing the simulation made a cycle between the folders, issue
31).
"""
from __future__ import annotations

import numpy as np

from .fringes import demo_scene, fringe_images

__all__ = ["simulate_and_measure_demo"]


def simulate_and_measure_demo(out_dir=None, width: int = 1000, height: int = 1000, rng=0):
    """Render fringe images of the example panel, measure them and return the scan (``make demo``).

    Writes ``left.png``, ``right.png``, ``rig.json`` and ``scan.ply`` to ``out_dir`` when given.

    Returns
    -------
    scan : StereoScan
    images : shapeverify.simulate.fringes.FringeImages
    """
    from pathlib import Path

    from shapeverify.camera.rig import save_rig
    from shapeverify.camera.stereo import measure

    model, rig, T = demo_scene(width, height)
    dent_at = model.faces[0].evaluate(np.array([[0.3, 0.6]]))[0]
    imgs = fringe_images(model, rig, T, period_mm=1.0, rng=rng, dent=(dent_at, 0.4, 8.0))
    scan = measure(imgs.rig, imgs.left, imgs.right)
    if out_dir is not None:
        import cv2

        from shapeverify.io.points import write_ply
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(out / "left.png"), imgs.left)
        cv2.imwrite(str(out / "right.png"), imgs.right)
        save_rig(imgs.rig, out / "rig.json")
        write_ply(out / "scan.ply", scan.points, scalars={"quality": scan.quality})
    return scan, imgs
