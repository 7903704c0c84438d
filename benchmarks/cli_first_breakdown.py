"""Where the plain first inspect's CPU goes: cli_start.main as `python -m shapeverify inspect
panel.svm scan.ply --tolerance 0.2 --json r_bd.json` runs it, timers on its parts (inclusive).
Run from WORK (the inputs of bench_cli.make_inputs): PYTHONPATH=src python cli_first_breakdown.py [MODEL.svm]
(MODEL.svm: the prepared model, default panel.svm; a tree's own `prepare` writes its own).
"""
import os, sys, time, json, resource, importlib
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF); return r.ru_utime + r.ru_stime
T0 = cpu()
acc = {}
def add(k, v): acc[k] = acc.get(k, 0.0) + v
sys.argv = ["shapeverify", "inspect", sys.argv[1] if len(sys.argv) > 1 else "panel.svm", "scan.ply", "--tolerance", "0.2", "--json", "r_bd.json"]
os.environ["SHAPEVERIFY_WORKER"] = "0"
import importlib.util
def wrap(modname, attr, key):
    m = importlib.import_module(modname); f = getattr(m, attr)
    def w(*a, **k):
        t = cpu()
        try: return f(*a, **k)
        finally: add(key, cpu() - t)
    setattr(m, attr, w)
t = cpu(); import shapeverify.cli_start as cs; from shapeverify import cli_worker; add("python + cli_start/cli_worker", cpu() - T0)
t = cpu(); import numpy; add("import numpy", cpu() - t)
t = cpu(); import numba; add("import numba", cpu() - t)
import numba.core.dispatcher as nd
oc = nd.Dispatcher.compile
depth = [0]
def comp(self, sig):
    depth[0] += 1; t = cpu()
    try: return oc(self, sig)
    finally:
        depth[0] -= 1
        if depth[0] == 0: add("kernels: cache load (%s)" % "numba", cpu() - t); acc["n_kernels"] = acc.get("n_kernels", 0) + 1
nd.Dispatcher.compile = comp
op = cs.preimport
def pre(*a):
    import gc
    t = cpu()
    # split: scipy.spatial import vs the rest
    import builtins
    bi = builtins.__import__
    def imp(name, *aa, **kk):
        if name == "scipy.spatial" and "scipy.spatial" not in sys.modules:
            t1 = cpu(); r = bi(name, *aa, **kk); add("import scipy.spatial (+linalg, special, sparse)", cpu() - t1); return r
        return bi(name, *aa, **kk)
    builtins.__import__ = imp
    try: op(*a)
    finally: builtins.__import__ = bi
    add("preimport total (incl. scipy, shapeverify, typer, eager kernels)", cpu() - t)
cs.preimport = pre
# after preimport the modules exist; wrap lazily via an import hook at the first call of main
om = cs.main
def main():
    return om()
import shapeverify.cli_common as cc
ow = cc._watch_compiles
def watch():
    ow()
    if "wrapped" not in acc:
        acc["wrapped"] = 1
        wrap("shapeverify.pipeline", "load_reference", "load the .svm (load_reference)")
        wrap("shapeverify.nearest.prepared", "for_model", "exact refiner tables (ExactCAD)")
        wrap("shapeverify.registration._noise", "scan_noise", "scan noise (k-d tree, quadrics)")
        wrap("shapeverify.pipeline", "inspect_scan", "inspect_scan (registration + evaluation)")
        wrap("shapeverify.pipeline", "run_inspection", "run_inspection (all the work)")
        try: wrap("shapeverify.report.result_json", "write_result_json", "JSON report")
        except Exception as e: print(e, file=sys.stderr)
cc._watch_compiles = watch
import gc
gcs = {"t": 0.0}
def cb(phase, info):
    if phase == "start": gcs["s"] = cpu()
    else: gcs["t"] += cpu() - gcs["s"]
gc.callbacks.append(cb)
try:
    code = main()
except SystemExit as e:
    code = e.code
acc["gc collections"] = gcs["t"]
acc["TOTAL (process, before teardown)"] = cpu()
acc.pop("wrapped", None)
print(json.dumps(acc))
