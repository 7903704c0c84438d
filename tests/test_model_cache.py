"""tests/model_cache.py (the suite's on-disk cache of imported and prepared shared parts) gives
bitwise what ``prepare(load_model(path))`` gives, from a fresh entry and from a stored one, and
never a stale entry: the key changes with the file's bytes, the arguments and the code."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import model_cache
from shapeverify.cad.examples import example_part_step
from shapeverify.cad.load import load_model
from shapeverify.nearest import prepare


def _arrays(prep, path):
    """The saved arrays; the model's file name (``source``) is compared on its own."""
    prep.save(path)
    with np.load(path) as z:
        out = {k: z[k] for k in z.files if k != "meta"}
    meta = json.loads(bytes(out.pop("model_meta")).decode())
    meta.pop("source")
    out["model_meta"] = np.frombuffer(json.dumps(meta, sort_keys=True).encode(), np.uint8)
    return out


def test_cached_prepared_is_bitwise_the_direct_preparation(tmp_path, monkeypatch):
    monkeypatch.setenv("SHAPEVERIFY_TEST_CACHE", str(tmp_path / "cache"))
    step = example_part_step(tmp_path / "panel.step")
    direct = _arrays(prepare(load_model(step), spacing=6.0), tmp_path / "direct.svm")
    built = model_cache.cached_prepared(step, spacing=6.0)              # made and stored
    assert built.model.source == str(step)
    (tmp_path / "copy").mkdir()
    again = example_part_step(tmp_path / "copy" / "panel.step")         # the same bytes
    stored = model_cache.cached_prepared(again, spacing=6.0)            # read back
    assert stored.model.source == str(again)
    for prep, name in ((built, "built"), (stored, "stored")):
        got = _arrays(prep, tmp_path / f"{name}.svm")
        assert got.keys() == direct.keys()
        bad = [k for k in direct if not np.array_equal(got[k], direct[k], equal_nan=True)]
        assert not bad, (name, bad)
    entries = sorted(p.name for p in (tmp_path / "cache").rglob("*.sv*") if "lock" not in p.name)
    assert len(entries) == 2, entries                # one model, one preparation


def test_cache_key_changes_with_the_bytes_the_arguments_and_the_code(tmp_path, monkeypatch):
    monkeypatch.setenv("SHAPEVERIFY_TEST_CACHE", str(tmp_path / "cache"))
    a = example_part_step(tmp_path / "a.step")
    b = example_part_step(tmp_path / "b.step", holes=())
    key = model_cache._entry(a, "prepared", {"spacing": 1.0}, ".svm")
    assert key == model_cache._entry(a, "prepared", {"spacing": 1.0}, ".svm")
    assert key != model_cache._entry(b, "prepared", {"spacing": 1.0}, ".svm")
    assert key != model_cache._entry(a, "prepared", {"spacing": 2.0}, ".svm")
    monkeypatch.setattr(model_cache, "code_key", lambda: "other sources")
    assert key != model_cache._entry(a, "prepared", {"spacing": 1.0}, ".svm")


def test_cached_pmi_and_arrays_are_what_their_builders_give_and_keyed_by_the_helper(
        tmp_path, monkeypatch):
    """``cached_pmi`` is ``read_pmi``'s dict; ``cached_arrays`` gives the builder's arrays bitwise,
    from a fresh entry and a stored one, and a new entry when the helper's source changes."""
    from shapeverify.cad.pmi import read_pmi

    monkeypatch.setenv("SHAPEVERIFY_TEST_CACHE", str(tmp_path / "cache"))
    step = example_part_step(tmp_path / "panel.step")
    direct = read_pmi(step)
    assert model_cache.cached_pmi(step) == direct            # built
    assert model_cache.cached_pmi(step) == direct            # read back
    calls = []

    def build(path, scale):
        calls.append(path)
        rng = np.random.default_rng(len(Path(path).read_bytes()))
        return rng.normal(size=(5, 3)) * scale, np.arange(7, dtype=np.int32)

    helper = tmp_path / "helper.py"
    helper.write_text("# v1\n")
    want = build(step, scale=2.5)
    for _ in range(2):
        got = model_cache.cached_arrays(step, "demo", build, code=(helper,), scale=2.5)
        assert len(got) == 2 and all(np.array_equal(g, w) and g.dtype == w.dtype
                                     for g, w in zip(got, want))
    assert len(calls) == 2                    # the direct call and the first cached one
    helper.write_text("# v2, another helper\n")
    model_cache.cached_arrays(step, "demo", build, code=(helper,), scale=2.5)
    assert len(calls) == 3


def _feature_fields(feats):
    """Every field of every feature, arrays as bytes (bitwise)."""
    import dataclasses

    return [tuple(v.tobytes() if isinstance(v, np.ndarray) else v
                  for v in (getattr(f, fl.name) for fl in dataclasses.fields(f))) for f in feats]


def test_cached_features_are_bitwise_model_features_of_a_fresh_import(tmp_path, monkeypatch):
    """``features=True``: the model (and the prepared model's model) carries what
    ``model_features`` and ``feature_notes`` compute on a fresh ``load_model``, from a fresh
    entry and a stored one; without it, nothing is put in place."""
    from shapeverify.characteristics.features import feature_notes, model_features

    monkeypatch.setenv("SHAPEVERIFY_TEST_CACHE", str(tmp_path / "cache"))
    step = example_part_step(tmp_path / "panel.step")
    fresh = load_model(step)
    want, notes = _feature_fields(model_features(fresh)), feature_notes(fresh)
    assert not hasattr(model_cache.cached_model(step), "_sv_features")
    for _ in range(2):                                   # built, then read back
        m = model_cache.cached_model(step, features=True)
        assert _feature_fields(m._sv_features) == want and list(m._sv_feature_notes) == notes
        assert _feature_fields(model_features(m)) == want
        prep = model_cache.cached_prepared(step, spacing=6.0, features=True)
        assert _feature_fields(model_features(prep)) == want


def test_a_part_is_prepared_and_its_features_computed_once_per_spacing(tmp_path, monkeypatch):
    """``allow_incomplete=True`` on a complete model shares the entry without it (the same
    preparation, bitwise); the prepared model's features are the model entry's (one features
    file per part, not one more per spacing); an incomplete model keeps its own key."""
    from shapeverify.characteristics.features import model_features

    monkeypatch.setenv("SHAPEVERIFY_TEST_CACHE", str(tmp_path / "cache"))
    step = example_part_step(tmp_path / "panel.step")
    plain = model_cache.cached_prepared(step, spacing=6.0, features=True)
    allowed = model_cache.cached_prepared(step, spacing=6.0, allow_incomplete=True,
                                          features=True)
    direct = _arrays(prepare(load_model(step), spacing=6.0, allow_incomplete=True),
                     tmp_path / "direct.svm")
    got = _arrays(allowed, tmp_path / "allowed.svm")
    assert not [k for k in direct if not np.array_equal(got[k], direct[k], equal_nan=True)]
    assert _feature_fields(model_features(allowed)) == _feature_fields(
        model_features(load_model(step)))
    assert _feature_fields(model_features(plain)) == _feature_fields(model_features(allowed))
    made = sorted(p.name.split("-")[1] + p.suffix for p in (tmp_path / "cache").rglob("*")
                  if p.is_file() and "lock" not in p.name)
    assert made == ["model.pkl", "model.svmodel", "prepared.svm"], made
    # an incomplete model: allow_incomplete is part of the key (without it prepare refuses)
    monkeypatch.setattr("shapeverify.cad.completeness.is_incomplete", lambda m: True)
    model_cache.cached_prepared(step, spacing=6.0, allow_incomplete=True)
    assert len(list((tmp_path / "cache").rglob("*-prepared-*.svm"))) == 2
