"""A prepared model's file stores the exact refiner's patch bounds (issue 32 item 7).

The first exact query of a process made them again from the model (Bézier nets of every knot
span, oriented boxes, the trims' test, the hierarchy: 0.06-0.2 s of the first ``inspect`` of
the example panel).  :meth:`Prepared.save` now writes them into the ``.svm`` and
:func:`load_prepared` reads them back, checked like the closest-point tree
(:func:`shapeverify.nearest.patches.check_arrays`: the kernels index them without bounds
checks); a file without them (older) or of another rule makes them again on first use.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import shapeverify as sv
from shapeverify.errors import ModelFileError
from shapeverify.nearest import _svm_checks, load_prepared
from shapeverify.nearest import patches as patches_mod
from shapeverify.nearest.exact import ExactCAD


def _arrays(path) -> tuple[dict, dict]:
    with np.load(path, allow_pickle=False) as z:
        a = {k: z[k] for k in z.files}
    return json.loads(bytes(a.pop("meta")).decode()), a


def _write(path, meta: dict, arrays: dict):
    """A file consistent with its header (the checksum recomputed: a forger's file)."""
    meta = dict(meta, sha256=_svm_checks.payload_digest(arrays))
    out = dict(arrays, meta=np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8))
    with open(path, "wb") as fh:
        np.savez(fh, **out)
    return path


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    """The bundled chamfered plate, prepared and saved; queries near and off its surface."""
    from shapeverify.cad.examples import chamfered_plate_step

    d = tmp_path_factory.mktemp("svm_patches")
    model = sv.load_model(chamfered_plate_step(d / "plate.step"))
    prep = sv.prepare(model, spacing=2.0)
    path = d / "plate.svm"
    prep.save(path)
    rng = np.random.default_rng(11)
    pts = prep.points.points[rng.choice(prep.n_points, 400, replace=False)]
    q = pts + rng.normal(0.0, 1.5, pts.shape)
    return path, q


class _Spy:
    """Counts the PatchBounds made from a model (not read from a file)."""

    def __init__(self, monkeypatch):
        self.made = 0
        made = patches_mod.PatchBounds.__init__

        def init(pb, *args, **kwargs):
            self.made += 1
            made(pb, *args, **kwargs)

        monkeypatch.setattr(patches_mod.PatchBounds, "__init__", init)


def test_svm_holds_the_patch_bounds_and_the_first_exact_query_does_not_make_them(
        plate, monkeypatch):
    path, q = plate
    meta, a = _arrays(path)
    stored = {k[len("exact_patch_"):]: v for k, v in a.items() if k.startswith("exact_patch_")}
    assert sorted(stored) == sorted(patches_mod.PatchBounds.FIELDS)
    assert meta["exact_patches"]["rule"] == patches_mod.PatchBounds.RULE
    prep = load_prepared(path)
    # the bounds made from the model now are the ones stored
    fresh = ExactCAD(prep.model, prep.spacing)
    for name, v in fresh.patches.to_arrays().items():
        assert np.array_equal(stored[name], v), name
    spy = _Spy(monkeypatch)
    got = prep.closest(q, exact=True)
    assert spy.made == 0                                # read from the file, not made again
    assert prep._exact.patches is prep._stored_patches
    # the answers of a refiner that made its own bounds
    idx, _ = prep._fast.nearest(q)
    foot, normal, dist, face, uv, onb = fresh.refine(q, idx, prep._fast, prep._face, prep._uv,
                                                     prep._other)
    assert np.array_equal(got.distances, dist) and np.array_equal(got.points, foot)
    assert np.array_equal(got.face, face) and np.array_equal(got.on_boundary, onb)


def test_svm_without_patch_bounds_makes_them_on_first_use(plate, tmp_path, monkeypatch):
    path, q = plate
    meta, a = _arrays(path)
    old = {k: v for k, v in a.items() if not k.startswith("exact_patch_")}
    meta.pop("exact_patches")
    prep = load_prepared(_write(tmp_path / "old.svm", meta, old))
    assert prep._stored_patches is None
    spy = _Spy(monkeypatch)
    got = prep.closest(q, exact=True)
    assert spy.made == 1
    want = load_prepared(path).closest(q, exact=True)
    assert np.array_equal(got.distances, want.distances)


def test_svm_patch_bounds_of_another_rule_are_made_again(plate, tmp_path, monkeypatch):
    path, q = plate
    meta, a = _arrays(path)
    meta["exact_patches"] = dict(meta["exact_patches"], rule=-1)
    prep = load_prepared(_write(tmp_path / "rule.svm", meta, a))
    assert prep._stored_patches is None
    spy = _Spy(monkeypatch)
    prep.closest(q[:50], exact=True)
    assert spy.made == 1


def _bad(a: dict, name: str, edit) -> dict:
    out = dict(a)
    v = a["exact_patch_" + name].copy()
    edit(v)
    out["exact_patch_" + name] = v
    return out


def _cycle(child):
    inner = np.flatnonzero(child >= 0)
    child[inner[-1]] = inner[0]                 # a later node names an earlier one's pair


def _shared(child):
    # two parents of one pair (a join): node j names the pair of an earlier node i (still a
    # later pair than j, so only the tree test sees it)
    inner = np.flatnonzero(child >= 0)
    i, j = next((i, j) for j in inner for i in inner if i < j < child[i])
    child[j] = child[i]


def _leaf_overflow(count):
    count[:] = 10 ** 6                          # leaves list more patches than there are


@pytest.mark.parametrize("name, edit, says", [
    ("face", lambda v: v.__setitem__(0, 10 ** 6), "face out of range"),
    ("face", lambda v: v.__setitem__(0, -1), "face out of range"),
    ("node_child", _cycle, "child index is out of range"),
    ("node_child", _shared, "not a tree"),
    ("node_child", lambda v: v.__setitem__(0, v.size + 5), "child index is out of range"),
    ("node_count", _leaf_overflow, "leaf lists patches out of range"),
    ("node_first", lambda v: v.__setitem__(slice(None), 2 ** 62), "out of range"),
    ("centre", lambda v: v.__setitem__((0, 0), np.nan), "NaN or infinite"),
])
def test_crafted_patch_bounds_are_an_error_not_a_crash(plate, tmp_path, name, edit, says):
    path, _ = plate
    meta, a = _arrays(path)
    if name == "node_child":
        assert np.count_nonzero(a["exact_patch_node_child"] >= 0) >= 2, "needs a deeper tree"
    crafted = _write(tmp_path / f"crafted-{name}.svm", meta, _bad(a, name, edit))
    with pytest.raises(ModelFileError) as err:
        load_prepared(crafted)
    assert says in str(err.value) and f"crafted-{name}.svm" in str(err.value)


def test_the_checks_pass_the_bounds_a_model_makes(plate):
    # the bounds of the plate, of every face: none rejected by the checks
    prep = load_prepared(plate[0])
    pb = ExactCAD(prep.model, prep.spacing).patches
    assert patches_mod.check_arrays(pb.to_arrays(), len(prep.model.faces)) is None
