"""Child process of tests/test_svm_integrity.py: loads ``.svm`` files, one path per stdin line,
and answers one line per file on stdout, so that a crash or an endless loop on a damaged file
ends this process (seen by the test), never pytest.

Usage: ``python _svm_fuzz_worker.py ORIGINAL.svm QUERIES.npy``; then per line ``PATH``:

* ``error <class name>`` -- ``load_prepared`` (or a query) raised a ShapeVerifyError/ValueError
  that names the file;
* ``unnamed <class name> <message>`` -- it raised one that does not name the file;
* ``other <class name> <message>`` -- it raised something else (a test failure);
* ``same`` -- it loaded, and the fast and exact answers to the queries equal the original's
  bit for bit;
* ``differs`` -- it loaded and answered, differently.
"""

import sys

import numpy as np


def answers(prep, q):
    fast = prep.closest(q)
    exact = prep.closest(q, exact=True)
    return [fast.distances, fast.points, fast.face, fast.index, exact.distances, exact.points,
            exact.face]


def main():
    from shapeverify.errors import ShapeVerifyError
    from shapeverify.nearest import load_prepared

    q = np.load(sys.argv[2])
    ref = answers(load_prepared(sys.argv[1]), q)
    out = sys.stdout
    out.write("ready\n")
    out.flush()
    for line in sys.stdin:
        path = line.strip()
        try:
            got = answers(load_prepared(path), q)
            same = all(a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
                       for a, b in zip(ref, got))
            out.write("same\n" if same else "differs\n")
        except (ShapeVerifyError, ValueError) as exc:
            if path.rsplit("/", 1)[-1] in str(exc):
                out.write(f"error {type(exc).__name__}\n")
            else:
                out.write(f"unnamed {type(exc).__name__} {str(exc)[:200]!r}\n")
        except Exception as exc:  # noqa: BLE001 - reported, the test fails on it
            out.write(f"other {type(exc).__name__} {str(exc)[:200]!r}\n")
        out.flush()


if __name__ == "__main__":
    main()
