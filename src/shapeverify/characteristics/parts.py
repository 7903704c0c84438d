"""Small in-memory CAD parts with features, for inspection plans (tests, examples, benchmarks).

:func:`bracket` is an inside corner: a 100 x 80 mm base plate (z = 0) with round holes, two
40 mm walls (x = 0 and y = 0) and a vertical cylindrical boss.  Every pose direction is
determined by it, a camera along (1, 1, 1) sees all of it, and its features are exact (planes,
circles, a rational cylinder), so measured values can be checked against closed forms.

Example
-------
>>> m = bracket()
>>> len(m.faces)
4
"""
from __future__ import annotations

import numpy as np

from ..cad.model import Face, Model
from ..cad.nurbs import NurbsSurface

__all__ = ["bracket", "BRACKET_HOLES", "BRACKET_BOSS", "circle_loop"]

#: holes of :func:`bracket`: (x, y, radius) in mm, through the base plate
BRACKET_HOLES = ((30.0, 40.0, 6.0), (62.0, 22.0, 4.5))
#: the boss of :func:`bracket`: (x, y, radius, height) in mm
BRACKET_BOSS = (75.0, 58.0, 8.0, 20.0)


def circle_loop(cx: float, cy: float, r: float, n: int = 512) -> np.ndarray:
    """(n, 2) polygon of a circle (clockwise: an inner loop)."""
    t = -np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def _bilinear(p00, p10, p01, p11) -> NurbsSurface:
    ctrl = np.array([[p00, p01], [p10, p11]], np.float64)
    return NurbsSurface(1, 1, [0, 0, 1, 1], [0, 0, 1, 1], ctrl)


def _cylinder(cx, cy, r, h) -> NurbsSurface:
    """Rational quadratic full cylinder (u around, v up), outward normal = Su x Sv."""
    w = np.sqrt(0.5)
    ang = np.arange(9) * np.pi / 4
    rr = np.where(np.arange(9) % 2 == 1, r / w, r)
    xy = np.column_stack([cx + rr * np.cos(ang), cy + rr * np.sin(ang)])
    ctrl = np.zeros((9, 2, 3))
    ctrl[:, 0, :2] = ctrl[:, 1, :2] = xy
    ctrl[:, 1, 2] = h
    wts = np.repeat(np.where(np.arange(9) % 2 == 1, w, 1.0)[:, None], 2, axis=1)
    ku = [0, 0, 0, .25, .25, .5, .5, .75, .75, 1, 1, 1]
    return NurbsSurface(2, 1, ku, [0, 0, 1, 1], ctrl, wts)


def bracket(holes=BRACKET_HOLES, boss=BRACKET_BOSS, size=(100.0, 80.0), wall: float = 40.0) -> Model:
    """An inside-corner bracket: base plate with holes, walls x = 0 and y = 0, a boss.

    Parameters
    ----------
    holes : sequence of (x, y, radius)
        Round holes through the base plate (mm), well inside it.
    boss : (x, y, radius, height) or None
        A vertical cylindrical boss standing on the plate (an open tube), or None.
    size : (length x, width y) of the base plate (mm)
    wall : height of the walls (mm)

    Returns
    -------
    Model
        Faces: 0 the base plate (+z), 1 the wall x = 0 (+x), 2 the wall y = 0 (+y), 3 the boss
        (when given; outward normals).  The walls' edges on the plate are shared, the rest free.
    """
    L, W = map(float, size)
    H = float(wall)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    base = _bilinear([0, 0, 0], [L, 0, 0], [0, W, 0], [L, W, 0])
    loops = [square] + [np.column_stack([(x + r * np.cos(t)) / L, (y + r * np.sin(t)) / W])
                        for x, y, r in holes
                        for t in [-np.linspace(0, 2 * np.pi, 512, endpoint=False)]]
    # base: u along x, v along y; edge v=0 (y=0) and u=0 (x=0) are shared with the walls
    free_outer = np.array([False, True, True, False])
    faces = [Face(base, tuple(loops), (free_outer,) + tuple(np.ones(len(lp), bool)
                                                           for lp in loops[1:]))]
    # wall x = 0: u along y, v along z -> Su x Sv = +x
    wx = _bilinear([0, 0, 0], [0, W, 0], [0, 0, H], [0, W, H])
    faces.append(Face(wx, (square,), (np.array([False, True, True, True]),)))
    # wall y = 0: u along z, v along x -> Su x Sv = +y
    wy = _bilinear([0, 0, 0], [0, 0, H], [L, 0, 0], [L, 0, H])
    faces.append(Face(wy, (square,), (np.array([True, True, True, False]),)))
    if boss is not None:
        bx, by, br, bh = map(float, boss)
        faces.append(Face(_cylinder(bx, by, br, bh), (square,), (np.ones(4, bool),)))
    return Model(tuple(faces), source="bracket (shapeverify.characteristics.parts)")
