"""A/B of a command's CPU in fresh processes, source trees interleaved (results_cli.md, eighth
session).  Inputs: bench_cli.make_inputs in WORK (default /tmp/cli8w).
Run: python benchmarks/ab_cli_start.py base=/path/src,new=/path/src N -m shapeverify inspect panel.svm scan.ply --tolerance 0.2 --json r.json
A tree may name its own prepared model (each tree's `prepare` writes its own .svm):
base=/path/src:panel.svm,new=/path/src:panel_new.svm, and the argument {svm} stands for it.
Not for `info`: the trees share the summary cache and each one's entry (its version) makes the
other import the file again; time `info` per tree with a SHAPEVERIFY_CACHE_DIR of its own.
"""
import os, resource, subprocess, sys, statistics, json
trees = dict(a.split("=") for a in sys.argv[1].split(","))
svm = {k: (v.split(":") + ["panel.svm"])[1] for k, v in trees.items()}
trees = {k: v.split(":")[0] for k, v in trees.items()}
n = int(sys.argv[2]); cmd = sys.argv[3:]
py = sys.executable
res = {k: [] for k in trees}
loads = []
def run(src, k):
    env = dict(os.environ); env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPATH"] = src; env["SHAPEVERIFY_WORKER"] = "0"; env["COLUMNS"] = "120"
    b = resource.getrusage(resource.RUSAGE_CHILDREN)
    argv = [svm[k] if c == "{svm}" else c for c in cmd]
    p = subprocess.run([py] + argv, env=env, cwd=os.environ.get("WORK", "/tmp/cli8w"), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    a = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert p.returncode in (0, 1, 3), p.stderr[-2000:]
    return a.ru_utime - b.ru_utime + a.ru_stime - b.ru_stime
for k, src in trees.items(): run(src, k)   # untimed
for i in range(n):
    loads.append(os.getloadavg()[0])
    for k, src in trees.items(): res[k].append(run(src, k))
for k, v in res.items():
    print(f"{k}: median {statistics.median(v):.3f} range {min(v):.3f}-{max(v):.3f}  {[round(x,2) for x in v]}")
print("load", [round(x,1) for x in loads])
