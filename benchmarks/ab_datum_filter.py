"""A/B of the datum-plane filter (:mod:`shapeverify.characteristics.datum_filter`): the same
independent scan (check_nist_plans.py's: perfect, hole moved, face tilted) inspected with the
plan twice -- the tangent plane of the raw points (RADIUS 0) and of the filtered ones -- and
every characteristic whose verdict or value changes printed.

    PYTHONPATH=src .venv/bin/python benchmarks/ab_datum_filter.py --files /tmp/nist_ftc_07_asme1_ap242-e2.stp --init
(takes check_nist_plans.py's options)."""
import sys

import check_nist_plans as C
from shapeverify.characteristics import datum_filter

_inspect = C.inspect_case
OUT = []


def both(prep, plan, P, rng, given_pose, data=None, feats=None, defect=None):
    import copy
    res = {}
    for r in (0.0, datum_filter.RADIUS_AB):
        datum_filter.RADIUS = r
        res[r] = _inspect(prep, plan, P, copy.deepcopy(rng), given_pose, data, feats, defect)
    a, b = res[0.0][0], res[datum_filter.RADIUS_AB][0]
    kind = defect["kind"] if defect else "perfect"
    va = [v["verdict"] for v in a.values()]
    vb = [v["verdict"] for v in b.values()]
    line = (f"AB {kind}: raw pass/fail/undecided {va.count('pass')}/{va.count('fail')}/"
            f"{va.count('undecided')} -> filtered {vb.count('pass')}/{vb.count('fail')}/"
            f"{vb.count('undecided')}")
    print(line, file=sys.stderr, flush=True)
    OUT.append(line)
    for k in a:
        x, y = a[k], b[k]
        if x["verdict"] != y["verdict"] or (isinstance(x["measured"], float) and isinstance(y["measured"], float) and abs(x["measured"] - y["measured"]) > 0.005):
            s = (f"  {k} {x['type']} {C._num(x['measured'])} U {C._num(x['uncertainty'])} {x['verdict']} -> "
                 f"{C._num(y['measured'])} U {C._num(y['uncertainty'])} {y['verdict']} ({y['relation']}) tol {C._num(x['upper'])}")
            print(s, file=sys.stderr, flush=True)
            OUT.append(s)
    return res[datum_filter.RADIUS_AB]


datum_filter.RADIUS_AB = 2.5
C.inspect_case = both
if __name__ == "__main__":
    C.main()
