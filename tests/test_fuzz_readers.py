"""Fuzzing of the scan readers and the service's upload path (issue 9, "hardened readers").

Every generated input -- structurally plausible files with lying headers, mutated valid files,
random bytes -- must end in one of two ways: a finite ``(N, 3)`` float64 array, or a *clean*
exception (a :class:`~shapeverify.errors.ShapeVerifyError` or ``ValueError`` with a message).
Never another exception type (MemoryError, OverflowError, IndexError, struct.error...), never a
hang (a guard per example on the process' CPU seconds, ``ITIMER_PROF``: hypothesis' wall-clock
deadline failed examples that the loaded machine only paused), and memory bounded by the
input size (tracemalloc on the absurd-size cases: a header that claims 10**12 vertices in a
200-byte file must fail before anything of that size is allocated).

The runs are derandomized (repeatable in CI) and sized to 11,950 generated inputs in total (plus
the fixed absurd-size cases): about 20 s of CPU.  The structured generators draw a seed from
hypothesis and build the file with ``random.Random(seed)`` (hypothesis' per-draw cost would
dominate otherwise); a failure is reported, and replayed, by its seed.
"""

from __future__ import annotations

import io
import logging
import math
import random
import struct
import tracemalloc

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cpu_bound import Hang, cpu_time_bound

from shapeverify.errors import ShapeVerifyError
from shapeverify.io.points import read_points
from shapeverify.service.body import parse_scan

HANG_SECONDS = 10.0  # one example reading < 10 kB must never take this long (even on a loaded machine)


def fuzz_settings(n: int):
    return settings(max_examples=n, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.filter_too_much, HealthCheck.large_base_example,
                                           HealthCheck.function_scoped_fixture])


def no_hang(seconds: float = HANG_SECONDS):
    """Abort the block with :class:`Hang` after ``seconds`` of CPU time."""
    return cpu_time_bound(seconds, "reader did not return")


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture(scope="module", autouse=True)
def _quiet_reader_warnings():
    """The reader logs dropped NaN rows as warnings; thousands of them only slow the run."""
    lg = logging.getLogger("shapeverify.io.points")
    old = lg.level
    lg.setLevel(logging.ERROR)
    yield
    lg.setLevel(old)


def assert_clean(fn, *args):
    """Call ``fn``: either finite (N>=1, 3) float64 points or a clean, explained exception."""
    try:
        with no_hang():
            pts = fn(*args)
    except Hang:
        raise
    except (ShapeVerifyError, ValueError) as exc:
        assert str(exc).strip(), f"{type(exc).__name__} without a message"
        return None
    assert isinstance(pts, np.ndarray) and pts.dtype == np.float64, type(pts)
    assert pts.ndim == 2 and pts.shape[1] == 3 and len(pts) >= 1, pts.shape
    assert np.isfinite(pts).all()
    return pts


def check_file(fuzz_dir, data: bytes, ext: str):
    path = fuzz_dir / f"f{ext}"
    path.write_bytes(data)
    return assert_clean(read_points, path)


# ------------------------------------------------------------------------------------ pieces
# The structured generators draw a seed (and a few choices) from hypothesis and build the bulk of
# the file with random.Random(seed): hypothesis' per-draw cost would otherwise dominate the run
# time, and a failing example is still reported (and replayed) by its seed.
NUMBER_TOKENS = ["0", "-0", "1", "-3", "42", "1.5", "-2.25", "1e3", "3.4e38", "1e308", "1e999", "-1e-999",
                 "nan", "NaN", "-inf", "inf", "Infinity", "1_0", "0x1p3", "+", "-", ".", "e", "1e",
                 "--1", "1..2", "", "x", "ply", "\x00", "\u00e9", "99999999999999999999999"]
ABSURD_COUNTS = [999999999999, 10**12, 2**31 - 1, 2**31, 2**32 + 1, 2**63, 10**30, 123456789]
COUNT_TEXT = ([str(i) for i in range(13)] + [str(c) for c in ABSURD_COUNTS]
              + ["-1", "-999999999999", "1e3", "0x10", "", "3.0", "ten", "\u0663"])
PLY_TYPES = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8",
             "int16", "uint16", "int32", "uint32", "float32", "float64"]
BAD_PLY_TYPES = ["long", "int64", "float16", "string", "list", "", "Float"]
PROP_NAMES = ["x", "y", "z", "nx", "red", "intensity", "vertex_indices", "q"]
SEEDS = st.integers(0, 2**32 - 1)


def _token(rng: random.Random, bad: float) -> str:
    r = rng.random()
    if r < bad:
        return rng.choice(NUMBER_TOKENS)
    if r < 0.85:
        return repr(rng.uniform(-1e3, 1e3))
    return str(rng.randint(-300, 300))


def _rows(rng: random.Random, n_rows: int, n_cols: int, sep: str = " ", bad: float = 0.0) -> str:
    """``n_rows`` lines of ``n_cols`` numbers; with probability ``bad`` a token is a strange one
    (NaN, inf, overflow, junk) and a line gets a wrong number of tokens."""
    out = []
    for _ in range(n_rows):
        k = n_cols if rng.random() >= bad else rng.randint(0, n_cols + 3)
        out.append(sep.join(_token(rng, bad) for _ in range(k)))
    return "\n".join(out)


def _ply_property(rng: random.Random) -> str:
    name = rng.choice(PROP_NAMES)
    r = rng.random()
    if r < 0.75:
        return f"property {rng.choice(PLY_TYPES)} {name}"
    if r < 0.9:
        return f"property list {rng.choice(PLY_TYPES)} {rng.choice(PLY_TYPES)} {name}"
    return f"property {rng.choice(BAD_PLY_TYPES + PLY_TYPES)}{rng.choice(['', ' ' + name, ' a b c'])}"


_ITEM = {"char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h", "ushort": "H",
         "uint16": "H", "int": "i", "int32": "i", "uint": "I", "uint32": "I", "float": "f", "float32": "f",
         "double": "d", "float64": "d"}


def random_ply(seed: int, fmt: str) -> bytes:
    """A PLY file with a plausible structure (an optional element before the vertices, extra and
    list properties, a body that matches the header) and a few injected faults: lying or absurd
    counts, wrong or unknown property types, list coordinates, bad tokens, NaN/inf, random
    bytes, truncation, a broken header line."""
    rng = random.Random(seed)
    fault = lambda p: rng.random() < p  # noqa: E731
    n = rng.randint(1, 12)
    elements = []  # (name, count, [(type, name) | ("list", ctype, itype, name)])
    if fault(0.3):
        elements.append(("face" if fault(0.5) else "camera", rng.randint(0, 3),
                         [("list", "uchar", "int", "vertex_indices")] if fault(0.7) else [("float", "k")]))
    vprops = [(rng.choice(["float", "double", "float32", "int", "short", "uchar"]), c) for c in "xyz"]
    for _ in range(rng.choice([0, 0, 1, 2])):
        vprops.insert(rng.randint(0, len(vprops)),
                      (rng.choice(PLY_TYPES), rng.choice(["nx", "red", "intensity", "q"]))
                      if fault(0.7) else ("list", rng.choice(["uchar", "int", "char"]), "float", "lst"))
    elements.append(("vertex", n, vprops))
    if fault(0.3):
        elements.append(("face", rng.randint(0, 4), [("list", "uchar", "int", "vertex_indices")]))
    # body, written from the true structure
    endian = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(fmt)
    chunks = []
    for _, count, props in elements:
        for _ in range(count):
            vals = []
            for prop in props:
                if prop[0] == "list":
                    k = rng.randint(0, 4)
                    vals.append((prop[1], k))
                    vals += [(prop[2], rng.randint(0, max(n - 1, 0)) if prop[2] == "int" else rng.uniform(-9, 9))
                             for _ in range(k)]
                else:
                    t = prop[0]
                    v = rng.uniform(-100, 100) if _ITEM[t] in "fd" else rng.randint(0, 100)
                    if _ITEM[t] in "fd" and fault(0.05):
                        v = rng.choice([math.nan, math.inf, -math.inf])
                    vals.append((t, v))
            if endian is None:
                chunks.append(" ".join(repr(v) if isinstance(v, float) else str(v) for _, v in vals) + "\n")
            else:
                chunks.append(b"".join(struct.pack(endian + _ITEM[t], v) for t, v in vals))
    body = "".join(chunks).encode() if endian is None else b"".join(chunks)
    if endian is None and fault(0.2):
        body = (_rows(rng, rng.randint(0, 12), 3 + len(vprops) - 3, bad=0.3) + "\n").encode("utf-8")
    elif endian is not None and fault(0.1):
        body = rng.randbytes(rng.randint(0, 2 * len(body) + 8))
    # header, with faults
    lines = ["ply", f"format {fmt} 1.0"] + (["comment fuzz"] if fault(0.3) else [])
    for name, count, props in elements:
        if fault(0.12):
            count = rng.choice(COUNT_TEXT)
        lines.append(f"element {name} {count}")
        for prop in props:
            if fault(0.05):
                lines.append(_ply_property(rng))
            elif prop[0] == "list":
                lines.append(f"property list {prop[1]} {prop[2]} {prop[3]}")
            else:
                lines.append(f"property {rng.choice(PLY_TYPES) if fault(0.05) else prop[0]} {prop[1]}")
    if fault(0.1):
        lines.insert(rng.randint(1, len(lines)), rng.choice(
            ["property float x", "element", "end_header", "obj_info hi", "bogus line", "", "format ascii",
             "element vertex 3", "property list uchar float x", f"format {rng.choice(['binary', 'ascii 2'])} 1.0"]))
    end = "end_header\n" if not fault(0.1) else rng.choice(["end_header\r\n", "end_header", "end_header  \n", ""])
    data = ("\n".join(lines) + "\n" + end).encode("utf-8") + body
    if fault(0.15):  # truncate anywhere, also inside the header
        data = data[: rng.randint(0, len(data))]
    return data


def random_pcd(seed: int, body_kind: str) -> bytes:
    rng = random.Random(seed)
    fault = lambda p: rng.random() < p  # noqa: E731
    fields = ["x", "y", "z"]
    for _ in range(rng.choice([0, 0, 1, 2])):
        fields.insert(rng.randint(0, 3), rng.choice(["rgb", "normal_x", "intensity"]))
    if fault(0.1):
        fields = [rng.choice(["x", "y", "z", "rgb"]) for _ in range(rng.randint(0, 4))]
    nf = len(fields)
    types = [rng.choice([("F", 4), ("F", 8), ("I", 2), ("U", 1), ("I", 4)]) for _ in range(nf)]
    counts = [1 if not fault(0.1) else 2 for _ in range(nf)]
    n = rng.randint(1, 12)

    def lie(values, junk):
        values = list(values)
        if values and fault(0.08):
            values[rng.randrange(len(values))] = rng.choice(junk)
        if fault(0.04):
            values = values[:-1] if rng.random() < 0.5 else values + [values[0] if values else "4"]
        return " ".join(str(v) for v in values if v is not None)

    absurd = [str(c) for c in ABSURD_COUNTS]
    header = {"VERSION": "0.7", "FIELDS": " ".join(fields),
              "SIZE": lie([s for _, s in types], ["3", "0", "-4", "x", "16"]),
              "TYPE": lie([t for t, _ in types], ["f", "Q", "", "D"]),
              "COUNT": lie(counts, ["0", "-1"] + absurd),
              "WIDTH": str(n) if not fault(0.1) else rng.choice(COUNT_TEXT), "HEIGHT": "1",
              "VIEWPOINT": "0 0 0 1 0 0 0", "POINTS": str(n) if not fault(0.15) else rng.choice(COUNT_TEXT),
              "DATA": body_kind if not fault(0.08) else rng.choice(["binary_compressed", "zip", "", "ASCII"])}
    lines = ["# .PCD v0.7"] + [f"{k} {v}" for k, v in header.items() if not fault(0.04)]
    if fault(0.05):
        rng.shuffle(lines)
    # body from the true structure
    ncol = sum(counts)
    if body_kind == "ascii":
        body = (_rows(rng, n, ncol, bad=0.05 if not fault(0.2) else 0.4) + "\n").encode("utf-8")
    else:
        parts = []
        for _ in range(n):
            for (t, sz), c in zip(types, counts):
                code = {("F", 4): "f", ("F", 8): "d", ("I", 2): "h", ("U", 1): "B", ("I", 4): "i"}[(t, sz)]
                for _ in range(c):
                    v = rng.uniform(-100, 100) if t == "F" else rng.randint(0, 100)
                    parts.append(struct.pack("<" + code, v))
        body = b"".join(parts)
        if fault(0.1):
            body = rng.randbytes(rng.randint(0, len(body) + 8))
    data = ("\n".join(lines) + "\n").encode("utf-8") + body
    if fault(0.15):
        data = data[: rng.randint(0, len(data))]
    return data


def random_table(seed: int) -> bytes:
    rng = random.Random(seed)
    sep = rng.choice([" ", ",", ";", "\t", ", ", "  "])
    n_cols = rng.choice([3, 3, 3, 3, 4, 6, 2, 1])
    bad = rng.choice([0.0, 0.0, 0.02, 0.1, 0.4])
    lines = _rows(rng, rng.randint(0, 25), n_cols, sep, bad=bad).split("\n")
    for _ in range(rng.choice([0, 0, 1, 2, 3])):
        lines.insert(rng.randint(0, len(lines)), rng.choice(
            ["# comment", "// comment", "x y z", "X,Y,Z,I", "", "   ", "\x00\x01", "1 2 3 # trailing"]))
    text = rng.choice(["\n", "\n", "\r\n", "\r"]).join(lines)
    return text.encode(rng.choice(["utf-8", "utf-8", "utf-8", "utf-16", "latin-1"]), errors="replace")


def ply_files():
    return st.builds(random_ply, SEEDS, st.sampled_from(["ascii", "binary_little_endian", "binary_big_endian"]))


def pcd_files():
    return st.builds(random_pcd, SEEDS, st.sampled_from(["ascii", "binary"]))


def table_files():
    return st.builds(random_table, SEEDS)


# valid files: stored values -> the expected points (what the file really holds, finite rows)
def _stored(pts: np.ndarray, code: str) -> np.ndarray:
    """``pts`` converted to the storage type ``code`` (ints: NaN->0, clipped to range)."""
    if code[0] in "iu":
        info = np.iinfo(code)
        return np.clip(np.nan_to_num(np.round(pts), posinf=info.max, neginf=info.min),
                       info.min, info.max).astype(code)
    with np.errstate(over="ignore", invalid="ignore"):
        return pts.astype(code)


def _ply_bytes(pts: np.ndarray, kind: str, ftype: str):
    code = {"float": "f4", "double": "f8", "int": "i4", "short": "i2", "uchar": "u1"}[ftype]
    arr = _stored(pts, code)
    head = (f"ply\nformat {kind} 1.0\nelement vertex {len(pts)}\n"
            + "".join(f"property {ftype} {c}\n" for c in "xyz") + "end_header\n").encode()
    if kind == "ascii":
        body = "\n".join(" ".join(repr(v.item()) for v in row) for row in arr).encode() + b"\n"
    else:
        body = arr.astype(("<" if kind == "binary_little_endian" else ">") + code).tobytes()
    return head + body, arr.astype(np.float64)


def _pcd_bytes(pts: np.ndarray, kind: str):
    arr = _stored(pts, "f4")
    head = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
            f"WIDTH {len(pts)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(pts)}\nDATA {kind}\n")
    if kind == "ascii":
        body = "\n".join(" ".join(repr(float(v)) for v in row) for row in arr).encode()
    else:
        body = arr.astype("<f4").tobytes()
    return head.encode() + body, arr.astype(np.float64)


def _npy_bytes(arr) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return buf.getvalue()


def random_valid(seed: int, fmt: str):
    """(bytes, extension, expected points) of a valid scan file; some rows NaN/inf."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 40))
    pts = rng.normal(scale=float(rng.choice([1.0, 100.0, 1e5])), size=(n, 3))
    if rng.random() < 0.5:
        pts.flat[rng.integers(0, pts.size, size=rng.integers(1, 4))] = rng.choice([np.nan, np.inf, -np.inf])
    if rng.random() < 0.1:
        pts[:] = np.nan
    if fmt == "ply_ascii":
        data, stored = _ply_bytes(pts, "ascii", str(rng.choice(["float", "double", "int"])))
        ext = ".ply"
    elif fmt in ("ply_le", "ply_be"):
        kind = "binary_little_endian" if fmt == "ply_le" else "binary_big_endian"
        data, stored = _ply_bytes(pts, kind, str(rng.choice(["float", "double", "int", "short", "uchar"])))
        ext = ".ply"
    elif fmt.startswith("pcd"):
        data, stored = _pcd_bytes(pts, fmt[4:])
        ext = ".pcd"
    elif fmt == "npy":
        stored = _stored(pts, str(rng.choice(["<f8", ">f4", "<f2", "<i4"])))
        data, ext = _npy_bytes(stored), ".npy"
        stored = stored.astype(np.float64)
    else:
        sep = "," if fmt == "csv" else str(rng.choice([" ", "\t", ";"]))
        text = "\n".join(sep.join(repr(float(v)) for v in row) for row in pts)
        if rng.random() < 0.5:
            text = sep.join(["x", "y", "z"]) + "\n" + text
        data, ext, stored = text.encode(), "." + fmt, pts
    return data, ext, stored[np.isfinite(stored).all(axis=1)]


VALID_FORMATS = st.sampled_from(["ply_ascii", "ply_le", "ply_be", "pcd_ascii", "pcd_binary", "xyz", "csv", "npy"])


def valid_files():
    return st.builds(random_valid, SEEDS, VALID_FORMATS)


def mutate(data: bytes, seed: int) -> bytes:
    """1-4 random byte-level mutations: bit flips, deletions, insertions, truncation,
    duplication, a header number rewritten to an absurd or negative value."""
    rng = random.Random(seed)
    data = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.choice(["flip", "delete", "insert", "truncate", "dup", "digit", "digit", "set"])
        pos = rng.randint(0, len(data))
        if op == "flip" and data:
            data[min(pos, len(data) - 1)] ^= 1 << rng.randint(0, 7)
        elif op == "delete":
            del data[pos: pos + rng.randint(1, 16)]
        elif op == "insert":
            data[pos:pos] = rng.randbytes(rng.randint(1, 16))
        elif op == "truncate":
            del data[pos:]
        elif op == "dup":
            data[pos:pos] = data[pos: pos + rng.randint(1, 64)]
        elif op == "digit":  # rewrite a number in the header: counts, sizes, shapes
            digits = [i for i, b in enumerate(data[:256]) if 48 <= b <= 57]
            if digits:
                i = rng.choice(digits)
                data[i:i + 1] = rng.choice([b"9999999999999", b"-1", b"0", b"7", b"e", b" ", b"00"])
        elif op == "set" and data:
            data[min(pos, len(data) - 1)] = rng.randint(0, 255)
    return bytes(data)


def mutated_files():
    return st.builds(lambda v, seed: (mutate(v[0], seed), v[1]), valid_files(), SEEDS)


# ------------------------------------------------------------------------------------ tests
@pytest.mark.slow
@fuzz_settings(2200)
@given(data=ply_files())
def test_fuzz_ply_structured(fuzz_dir, data):
    check_file(fuzz_dir, data, ".ply")


@pytest.mark.slow
@fuzz_settings(600)
@given(case=valid_files())
def test_valid_files_read_back_exactly(fuzz_dir, case):
    """The generators' valid files are read back to exactly their finite rows (so the mutation
    tests start from files the readers really accept); an all-NaN file is an error."""
    data, ext, expected = case
    got = check_file(fuzz_dir, data, ext)
    if len(expected) == 0:
        assert got is None
    else:
        assert got is not None
        np.testing.assert_array_equal(got, expected)


@pytest.mark.slow
@fuzz_settings(2500)
@given(case=mutated_files())
def test_fuzz_mutated_valid_files(fuzz_dir, case):
    data, ext = case
    check_file(fuzz_dir, data, ext)


@pytest.mark.slow
@fuzz_settings(1500)
@given(data=pcd_files())
def test_fuzz_pcd_structured(fuzz_dir, data):
    check_file(fuzz_dir, data, ".pcd")


@pytest.mark.slow
@fuzz_settings(1500)
@given(data=table_files(), ext=st.sampled_from([".xyz", ".txt", ".csv"]))
def test_fuzz_xyz_csv(fuzz_dir, data, ext):
    check_file(fuzz_dir, data, ext)


NPY_DTYPES = ["<f8", ">f8", "<f4", "<f2", "<i2", "<u1", "|b1", "<c8", "<i8", "<M8[s]", "<U3", "|S2"]
NPY_SHAPES = [(5, 3), (4, 2), (3, 7), (0, 3), (6,), (), (2, 3, 2), (1, 3), (17, 3), (9, 4)]
NPY_SHAPE_LIES = ["(999999999999, 3)", "(10000000, 3)", "(-1, 3)", "(3, -5)", "(2**40, 3)", "(3,)",
                  "'a'", "(1e3, 3)", "None", "(99999999999999999999999999, 3)", "((((((", "(1, 3"]
NPY_DESCR_LIES = ["", "", "'|O'", "'<f16'", "'x'", "[('x', '<f8')]", "'<f8'", "'<V8'"]
NPY_STRUCTS = [(("x", "y", "z"), ["<f8"] * 3), (("x", "y", "z", "w"), ["<f4", "<i4", "<u2", "<f8"]),
               (("x", "y"), ["<f8", "<f8"]), (("a", "b", "c"), ["<f8"] * 3),
               (("x", "y", "z"), ["|S3", "<f8", "<f8"]), (("x", "y", "z"), ["<f8", "<f8", ("<f8", (2,))])]


def random_npy(seed: int, kind: str) -> bytes:
    """A .npy: random bit patterns (so NaN/inf/subnormals too) of a random dtype and shape, a
    structured array, or a header that lies about the shape or dtype of the data behind it."""
    rng = random.Random(seed)
    if kind == "structured":
        names, codes = rng.choice(NPY_STRUCTS)
        dt = np.dtype(list(zip(names, codes)))
        n = rng.randint(0, 10)
        return _npy_bytes(np.frombuffer(rng.randbytes(n * dt.itemsize), dtype=dt, count=n))
    dtype = np.dtype(rng.choice(NPY_DTYPES[:8]) if kind == "plain" else rng.choice(NPY_DTYPES))
    shape = rng.choice(NPY_SHAPES)
    count = int(np.prod(shape))
    raw = rng.randbytes(count * dtype.itemsize)
    if dtype.kind in "MUS":
        arr = np.zeros(shape, dtype)
    else:
        arr = np.frombuffer(raw, dtype=dtype, count=count).reshape(shape)
    data = _npy_bytes(arr)
    if kind == "lie":  # keep the body, rewrite the header's shape or type
        text = data[10: data.index(b"\n") + 1].decode("latin-1")
        text = text.replace(repr(arr.shape), rng.choice(NPY_SHAPE_LIES), 1)
        descr = rng.choice(NPY_DESCR_LIES)
        if descr:
            text = text.replace(repr(dtype.str), descr, 1)
        header = text.encode("latin-1")
        data = data[:8] + struct.pack("<H", len(header)) + header + data[10 + len(header):]
    return data


def npy_files():
    return st.builds(random_npy, SEEDS, st.sampled_from(["plain", "plain", "structured", "lie", "lie"]))


@pytest.mark.slow
@fuzz_settings(1500)
@given(data=npy_files())
def test_fuzz_npy(fuzz_dir, data):
    check_file(fuzz_dir, data, ".npy")


@pytest.mark.slow
@fuzz_settings(800)
@given(data=st.binary(max_size=3000), ext=st.sampled_from([".ply", ".pcd", ".xyz", ".csv", ".npy", ".txt"]),
       prefix=st.sampled_from([b"", b"ply\n", b"\x93NUMPY\x01\x00", b"VERSION 0.7\n", b"1 2 3\n"]))
def test_fuzz_random_bytes(fuzz_dir, data, ext, prefix):
    check_file(fuzz_dir, prefix + data, ext)


CONTENT_TYPES = st.one_of(
    st.sampled_from([None, "", "application/octet-stream", "text/plain", "text/plain; charset=utf-8",
                     "text/csv", "text/x-xyz", "application/x-npy", "application/ply", "model/ply",
                     "application/x-pcd", "image/png", "multipart/form-data; boundary=x",
                     "application/json"]),
    st.text(max_size=30),
)


@pytest.mark.slow
@fuzz_settings(1200)
@given(body=st.one_of(mutated_files().map(lambda c: c[0]), valid_files().map(lambda c: c[0]), ply_files(),
                      pcd_files(), table_files(), npy_files(), st.binary(max_size=2000)),
       content_type=CONTENT_TYPES)
def test_fuzz_upload_path(body, content_type):
    """parse_scan (what POST /inspect calls): a result or a ShapeVerifyError/ValueError, which
    the service maps to 415/422 -- nothing that would become a 500."""
    assert_clean(parse_scan, body, content_type)


# ------------------------------------------------------------------------- memory bound
def _npy_claiming(shape, descr="<f8", body=b"\0" * 96) -> bytes:
    bb = io.BytesIO()
    np.lib.format.write_array_header_1_0(bb, {"descr": descr, "fortran_order": False, "shape": shape})
    return bb.getvalue() + body


ABSURD = [
    ("ply_binary_1e12", ".ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 999999999999\n"
     b"property float x\nproperty float y\nproperty float z\nend_header\n" + b"\0" * 60),
    ("ply_ascii_1e12", ".ply", b"ply\nformat ascii 1.0\nelement vertex 999999999999\n"
     b"property float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n4 5 6\n"),
    ("ply_face_first_1e12", ".ply", b"ply\nformat binary_little_endian 1.0\nelement face 999999999999\n"
     b"property list uchar int vertex_indices\nelement vertex 1\nproperty float x\nproperty float y\n"
     b"property float z\nend_header\n" + b"\3" + b"\0" * 40),
    ("ply_list_len_4e9", ".ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 2\n"
     b"property list uint int q\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
     + b"\xff\xff\xff\xff" + b"\0" * 40),
    ("ply_negative_list_len", ".ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 999999999\n"
     b"property list char int q\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
     + b"\xff" + b"\0" * 40),
    ("pcd_binary_1e12", ".pcd", b"VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
     b"WIDTH 999999999999\nHEIGHT 1\nPOINTS 999999999999\nDATA binary\n" + b"\0" * 60),
    ("pcd_count_1e12", ".pcd", b"VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1000000000000\n"
     b"POINTS 5\nDATA binary\n" + b"\0" * 60),
    ("pcd_ascii_1e12", ".pcd", b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 999999999999\n"
     b"DATA ascii\n1 2 3\n"),
    ("npy_1e12", ".npy", _npy_claiming((10**12, 3))),
    ("npy_1e7", ".npy", _npy_claiming((10**7, 3))),
    ("npy_2e40_f1", ".npy", _npy_claiming((2**40,), "|u1")),
    ("npy_structured_1e9", ".npy", _npy_claiming((10**9,), [("x", "<f8"), ("y", "<f8"), ("z", "<f8")])),
]


@pytest.mark.parametrize("name,ext,data", ABSURD, ids=[a[0] for a in ABSURD])
def test_absurd_sizes_fail_fast_without_allocating(fuzz_dir, name, ext, data):
    """A small file whose header claims a huge size: a clean error, in well under a second, with
    peak traced memory bounded by a small multiple of the input size."""
    assert len(data) < 400
    path = fuzz_dir / f"absurd{ext}"
    path.write_bytes(data)
    for fn, arg in ((read_points, path), (parse_scan, data)):
        tracemalloc.start()
        try:
            with no_hang(2.0), pytest.raises((ShapeVerifyError, ValueError)) as info:
                fn(arg)
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
        assert str(info.value)
        assert peak < 256 * 1024 + 200 * len(data), f"{name}: peak {peak} bytes for {len(data)} input bytes"


@pytest.mark.slow
@settings(max_examples=150, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(case=st.one_of(ply_files().map(lambda d: (d, ".ply")), pcd_files().map(lambda d: (d, ".pcd")),
                      npy_files().map(lambda d: (d, ".npy")), mutated_files()))
def test_fuzz_memory_bounded(fuzz_dir, case):
    """Peak traced memory of a read stays within a fixed multiple of the input size."""
    data, ext = case
    tracemalloc.start()
    try:
        check_file(fuzz_dir, data, ext)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1024 * 1024 + 400 * len(data), f"peak {peak} bytes for {len(data)} input bytes"
