"""The warm-up's inputs and runs for the commands beyond ``info``/``prepare``/``inspect``
(issue 32 item 3): ``inspect --plan`` (with its PDF), ``unwrap`` (every method), ``hologram``
(with and without a reference, with propagation), ``fit`` (curve, surface, every element with
least squares and a robust loss) and ``measure`` (both phase methods, with and without a model).

Each input is small (tens of pixels, hundreds of points): what is compiled depends on the types
the commands pass to the kernels, not on the sizes, so a small input compiles the same kernels
as a user's large one.  :func:`run_all` is called by :func:`shapeverify.warmup.warm_up`; each
command runs as its own process, as a user runs it.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

logger = logging.getLogger(__name__)

__all__ = ["PLAN", "run_all", "element_points", "noisy_phase", "library_variants",
           "global_search"]

#: an inspection plan of the bundled example panel: its hole and its whole skin
PLAN = """units: mm
alignment: {{type: best_fit}}
characteristics:
  - {{name: H1, type: hole, near: [{x}, {y}, 0], diameter: {{tol: 0.5}}, position: {{tol: 0.6}}}}
  - {{name: SKIN, type: surface_profile, faces: all, tol: 0.4}}
"""

ELEMENTS = ("sphere", "cylinder", "cone", "plane", "line", "circle")


def element_points(element: str, n: int = 240, rng=0):
    """``(n, 3)`` points on a ``element`` (mm, 0.01 mm noise): the fit command's input."""
    import numpy as np

    from ._random import generator

    g = generator(rng)
    a, b = g.uniform(0.0, 2.0 * np.pi, n), g.uniform(-1.0, 1.0, n)
    if element == "sphere":
        t = np.arccos(g.uniform(0.2, 1.0, n))          # a cap, as a probe reaches it
        p = 12.0 * np.column_stack([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)])
        p += [5.0, -3.0, 2.0]
    elif element == "cylinder":
        p = np.column_stack([6.0 * np.cos(a), 6.0 * np.sin(a), 20.0 * b])
    elif element == "cone":
        z = 5.0 + 10.0 * (b + 1.0)
        r = z * np.tan(np.radians(20.0))
        p = np.column_stack([r * np.cos(a), r * np.sin(a), z])
    elif element == "plane":
        p = np.column_stack([30.0 * b, 20.0 * g.uniform(-1, 1, n), 0.0 * b])
        p[:, 2] = 0.1 * p[:, 0] - 0.2 * p[:, 1] + 4.0
    elif element == "line":
        p = np.outer(40.0 * b, [0.6, 0.8, 0.0]) + [1.0, 2.0, 3.0]
    elif element == "circle":
        p = np.column_stack([8.0 * np.cos(a), 8.0 * np.sin(a), 0.0 * b]) + [2.0, 1.0, 0.0]
    else:
        raise ValueError(f"unknown element {element!r}; one of {', '.join(ELEMENTS)}")
    return p + g.normal(scale=0.01, size=p.shape)


def noisy_phase(h: int, w: int):
    """An ``(h, w)`` unwrapped phase (a bowl and a tilt) with a noisy patch: the patch makes
    residues (18 on 40 x 48).  Without residues the methods take their no-residue shortcuts: a
    smooth map left the minimum-cost flow (min_cost_flow, its cost kernels, heap and search) and
    path following's local frequency to a user's first noisy map (17 top-level kernels reached
    with the patch, 12 without; measured in one process with the dispatchers' statistics)."""
    import numpy as np

    from ._random import generator

    y, x = np.mgrid[0:h, 0:w]
    phi = 0.004 * ((x - w / 2) ** 2 + (y - 0.45 * h) ** 2) + 0.05 * x
    a, b = int(0.65 * h), int(0.62 * w)
    phi[a:a + h // 4, b:b + w // 4] += generator(7).normal(scale=1.6, size=(h // 4, w // 4))
    return phi


def _plan(work: Path, run, step: Path, svm: Path, scan: Path) -> None:
    from shapeverify.cad.examples import PANEL_HOLE

    x, y, _ = PANEL_HOLE
    plan = work / "plan.yaml"
    plan.write_text(PLAN.format(x=x, y=y))
    run(["inspect", svm, scan, "--tolerance", "0.2", "--plan", plan, "--pdf", work / "r.pdf",
         "--json", work / "rp.json", "--report", work / "rp.html"], work)


def _unwrap(work: Path, run) -> None:
    import numpy as np

    from shapeverify.phase import wrap
    from shapeverify.phase.regularised import DATA_METHODS

    phi = noisy_phase(40, 48)
    np.save(work / "psi.npy", wrap(phi))
    np.save(work / "psi32.npy", wrap(phi).astype(np.float32))
    mask = np.ones(phi.shape, np.uint8)
    mask[:4, :6] = 0
    np.save(work / "mask.npy", mask)
    for method in DATA_METHODS:
        run(["unwrap", work / "psi.npy", "-o", work / f"phi_{method}.npy", "--method", method],
            work)
    run(["unwrap", work / "psi32.npy", "-o", work / "phi32.npy", "--mask", work / "mask.npy",
         "--plot", work / "phi.png"], work)


def _hologram(work: Path, run) -> None:
    import numpy as np

    from shapeverify.simulate.hologram import dual_wavelength_holograms, grooved_plate

    l1, lam, pitch = 632.8e-6, 0.4, 0.05
    l2 = l1 * lam / (lam - l1)
    depth, _ = grooved_plate((64, 64), pitch, 1.0, 0.5)
    h1, h2 = dual_wavelength_holograms(depth, l1, l2, pixel_pitch=pitch, noise=0.02, bits=12,
                                       rng=3)
    np.save(work / "h1.npy", h1.intensity.astype(np.uint16))
    np.save(work / "h2.npy", h2.intensity.astype(np.uint16))
    np.save(work / "cad.npy", depth)
    base = ["hologram", work / "h1.npy", work / "h2.npy", "--lambda1", str(l1),
            "--lambda2", str(l2)]
    run(base + ["-o", work / "depth.npy"], work)
    run(base + ["-o", work / "depth_ref.npy", "--reference", work / "cad.npy", "--pitch",
                str(pitch), "--distance", "0.5"], work)


def _fit(work: Path, run) -> None:
    import numpy as np

    t = np.linspace(0.0, 1.0, 200)
    np.savetxt(work / "curve.xyz", np.column_stack([100 * t, 20 * np.sin(4 * t), 5 * t ** 2]))
    u, v = np.meshgrid(np.linspace(0, 1, 24), np.linspace(0, 1, 20))
    np.savetxt(work / "patch.xyz", np.column_stack([60 * u.ravel(), 40 * v.ravel(),
                                                    3 * np.sin(3 * u.ravel()) * v.ravel()]))
    for method in ("odr", "varpro", "fixed"):
        run(["fit", work / "curve.xyz", "--ctrl", "8", "--method", method,
             "-o", work / f"curve_{method}.json"], work)
        run(["fit", work / "patch.xyz", "--surface", "--ctrl", "6", "--method", method,
             "-o", work / f"patch_{method}.json"], work)
    for element in ELEMENTS:
        np.savetxt(work / f"{element}.xyz", element_points(element))
        for loss in ("l2", "tukey"):
            run(["fit", work / f"{element}.xyz", "--element", element, "--loss", loss,
                 "-o", work / f"{element}_{loss}.json"], work)


def _measure(work: Path, run) -> None:
    try:
        import cv2
    except ImportError:
        logger.info("  warm-up: measure skipped (OpenCV is not installed: pip install "
                    "opencv-python-headless)")
        return
    import numpy as np

    from shapeverify.camera.rig import save_rig
    from shapeverify.nearest import prepare
    from shapeverify.simulate.fringes import demo_scene, fringe_images

    model, rig, T = demo_scene(128, 128)
    imgs = fringe_images(model, rig, T, period_mm=1.0, rng=0)
    cv2.imwrite(str(work / "left.png"), imgs.left)
    cv2.imwrite(str(work / "right.png"), imgs.right)
    save_rig(imgs.rig, work / "rig.json")
    (work / "pose.json").write_text(json.dumps({"T_left_model": np.asarray(T).tolist()}))
    prepare(model, spacing=2.0).save(work / "wavy.svm")
    base = ["measure", work / "rig.json", work / "left.png", work / "right.png"]
    for method in ("ftp", "wff"):
        run(base + ["-o", work / f"m_{method}.ply", "--method", method], work)
    run(base + ["-o", work / "m_model.ply", "--model", work / "wavy.svm", "--pose",
                work / "pose.json"], work)


def run_all(work: Path, run, say, *, step: Path, svm: Path, scan: Path) -> None:
    """Run every command beyond ``info``/``prepare``/``inspect`` once on small inputs made in
    ``work``; ``run(argv, cwd)`` runs one command, ``say(text)`` reports each step."""
    say("inspecting with a plan (characteristics, PDF)")
    _plan(work, run, step, svm, scan)
    say("unwrapping a phase map (every method)")
    _unwrap(work, run)
    say("two-wavelength holograms")
    _hologram(work, run)
    say("fitting curves, surfaces and elements")
    _fit(work, run)
    say("measuring fringe images (stereo)")
    _measure(work, run)


def library_variants() -> None:
    """Call the phase and fitting functions with the arrays other programs hand over: a
    read-only, a float32 and a Fortran-ordered one (the command line always passes writeable
    C-ordered float64, a library caller may not)."""
    import numpy as np

    from shapeverify.fitting import fit_curve, fit_plane, fit_sphere
    from shapeverify.phase import unwrap, wrap

    psi = wrap(noisy_phase(32, 40))
    t = np.linspace(0.0, 1.0, 120)
    curve = np.column_stack([50 * t, 10 * np.sin(3 * t), t ** 2])
    for make in (_read_only, lambda a: a.astype(np.float32), np.asfortranarray):
        unwrap(make(psi))
        unwrap(make(psi), method="quality")
        fit_curve(make(curve), n_ctrl=8)
        for loss in ("l2", "tukey"):
            fit_plane(make(element_points("plane", 80)), loss=loss)
            fit_sphere(make(element_points("sphere", 80)), loss=loss)


def _read_only(a):
    b = a.copy()
    b.setflags(write=False)
    return b


def global_search(svm: Path, scan: Path) -> None:
    """The search with no start (``registration.global_alignment``: FPFH features, RANSAC,
    Kabsch) on the simulated scan of the panel, moved far from the model: ``inspect`` takes it
    when the scan's pose is unknown, and the warm-up's own scan starts near the model."""
    import numpy as np

    import shapeverify as sv
    from shapeverify.registration import global_alignment

    prep = sv.load_prepared(svm)
    points = sv.read_points(scan)
    c, s = np.cos(1.0), np.sin(1.0)
    moved = points @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T + [40.0, -25.0, 10.0]
    global_alignment(np.ascontiguousarray(moved), prep)
