"""Partial references (issue 30 item 5): a scan of a part of a mesh or point-cloud reference can
pass when the inspection is limited to a region of the reference (a box, or what the scan saw)."""

from __future__ import annotations

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.cad.model import Model
from shapeverify.nearest import prepare
from shapeverify.partial import crop_model, inspect_partial

NOISE = 0.02
BUMPS = ((12.0, 12.0), (18.0, 24.0), (40.0, 20.0))   # a sheet with bumps: a patch registers


def _height(x, y):
    z = 6.0 * np.sin(x / 25.0) * np.cos(y / 30.0)
    for bx, by in BUMPS:
        z = z + 2.0 * np.exp(-((x - bx) ** 2 + (y - by) ** 2) / (2 * 3.0 ** 2))
    return z


def _normal(x, y, h=1e-5):
    hx = (_height(x + h, y) - _height(x - h, y)) / (2 * h)
    hy = (_height(x, y + h) - _height(x, y - h)) / (2 * h)
    n = np.column_stack([-hx, -hy, np.ones_like(x)])
    return n / np.linalg.norm(n, axis=1)[:, None]


def sheet_points(spacing, rng, box, noise=0.0, dent=None, stratified=False):
    """Points on the bumpy sheet over ``box`` (x0, x1, y0, y1): one random point per
    ``spacing`` square (``stratified``) or uniform in (x, y); offset along the normal by noise
    and a Gaussian dent (depth, x, y, sigma).  Returns (points, signed offsets)."""
    x0, x1, y0, y1 = box
    if stratified:
        X, Y = np.meshgrid(np.arange(x0, x1, spacing), np.arange(y0, y1, spacing), indexing="ij")
        x = X.ravel() + rng.uniform(0, spacing, X.size)
        y = Y.ravel() + rng.uniform(0, spacing, X.size)
        keep = (x < x1) & (y < y1)
        x, y = x[keep], y[keep]
    else:
        n = int(round((x1 - x0) * (y1 - y0) / spacing ** 2))
        x, y = rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)
    d = rng.normal(0.0, noise, x.size) if noise else np.zeros(x.size)
    if dent is not None:
        depth, cx, cy, s = dent
        d = d - depth * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
    return np.column_stack([x, y, _height(x, y)]) + d[:, None] * _normal(x, y), d


def _sheet_mesh(w=60.0, h=40.0, step=0.5):
    xs, ys = np.arange(0.0, w + 1e-9, step), np.arange(0.0, h + 1e-9, step)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), _height(X.ravel(), Y.ravel())])
    ny = ys.size
    i, j = np.meshgrid(np.arange(xs.size - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    T = np.concatenate([np.column_stack([a, a + ny, a + ny + 1]),
                        np.column_stack([a, a + ny + 1, a + 1])]).astype(np.int32)
    return Model(faces=(), source="sheet mesh", kind="mesh", vertices=V, triangles=T)


@pytest.fixture(scope="module")
def mesh_prep():
    return prepare(_sheet_mesh())


PATCH = (8.0, 22.0, 6.0, 30.0)          # the scanned patch: about 14 % of the 60 x 40 sheet


def test_a_partial_scan_of_a_mesh_is_incomplete_against_the_whole_and_passes_on_what_it_saw(
        mesh_prep):
    rng = np.random.default_rng(1)
    scan, _ = sheet_points(0.7, rng, PATCH, noise=NOISE, stratified=True)
    whole = sv.inspect(mesh_prep, scan, tolerance=2 * NOISE)
    assert whole.verdict == "incomplete", whole.reasons
    seen = inspect_partial(mesh_prep, scan, seen=True, tolerance=2 * NOISE)
    assert seen.verdict == "pass", seen.reasons
    assert "reference limited to the part the scan saw" in seen.reasons[1]
    assert seen.coverage.fraction > 2 * whole.coverage.fraction
    boxed = inspect_partial(mesh_prep, scan, box=((6.0, 4.0, -10.0), (24.0, 32.0, 10.0)),
                            tolerance=2 * NOISE)
    assert boxed.verdict == "pass", boxed.reasons
    assert "the box [6.0, 4.0, -10.0] .. [24.0, 32.0, 10.0] mm" in boxed.reasons[1]
    # the box is larger than the patch: its coverage is the patch's share of it
    assert 0.2 < boxed.coverage.fraction < seen.coverage.fraction


def test_a_dent_in_the_seen_part_still_fails(mesh_prep):
    rng = np.random.default_rng(2)
    scan, _ = sheet_points(0.7, rng, PATCH, noise=NOISE, stratified=True,
                           dent=(0.3, 15.0, 18.0, 2.5))
    res = inspect_partial(mesh_prep, scan, seen=True, tolerance=2 * NOISE)
    assert res.verdict == "fail" and len(res.regions) == 1, res.reasons
    assert abs(res.regions[0].extreme + 0.3) < 0.03


def test_a_partial_scan_of_a_point_cloud_reference_passes_on_what_it_saw():
    rng = np.random.default_rng(3)
    # 0.5 mm: at 1 mm random points the bumps (sigma 3 mm) are not resolved to the tolerance
    # (fitted surface off by up to 0.09 mm at their tops; 0.011 mm at 0.5 mm)
    golden, _ = sheet_points(0.5, rng, (0.0, 60.0, 0.0, 40.0))
    prep = prepare(Model(faces=(), source="golden cloud", kind="points", vertices=golden))
    scan, _ = sheet_points(0.7, rng, PATCH, noise=NOISE, stratified=True)
    assert sv.inspect(prep, scan, tolerance=2 * NOISE).verdict == "incomplete"
    res = inspect_partial(prep, scan, seen=True, tolerance=2 * NOISE)
    assert res.verdict == "pass", res.reasons
    assert "reference points" in res.reasons[1]


def test_mesh_feet_past_the_outline_are_on_the_boundary(mesh_prep):
    rng = np.random.default_rng(4)
    scan, _ = sheet_points(0.7, rng, (40.0, 70.0, 0.0, 40.0), noise=NOISE)
    near = mesh_prep.closest(scan, exact=True)
    assert near.on_boundary[scan[:, 0] > 60.2].all()          # (noise moves points 0.02 mm)
    assert not near.on_boundary[scan[:, 0] < 59.8].any()


def test_bad_regions_are_refused_with_a_clear_message(mesh_prep):
    m = mesh_prep.model
    with pytest.raises(ValueError, match="no triangles .* lie in the box"):
        crop_model(m, box=((100, 100, 100), (200, 200, 200)))
    with pytest.raises(ValueError, match="lower < upper"):
        crop_model(m, box=((0, 0, 0), (0, 10, 10)))
    with pytest.raises(ValueError, match="either box"):
        crop_model(m)
    with pytest.raises(ValueError, match="one entry per triangle"):
        crop_model(m, keep=np.ones(3, bool))
    from shapeverify.cad.examples import wavy_panel

    with pytest.raises(ValueError, match="faces="):
        crop_model(wavy_panel(), box=((0, 0, 0), (1, 1, 1)))
    kept = crop_model(m, box=((0, 0, -10), (10, 10, 10)))
    assert len(kept.triangles) == 800 and kept.vertices.shape[0] == 441
