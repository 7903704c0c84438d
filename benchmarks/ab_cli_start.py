"""A/B of a command's CPU in fresh processes, source trees interleaved (results_cli.md, eighth
session).  Inputs: bench_cli.make_inputs in WORK (default /tmp/cli8w).
Run: python benchmarks/ab_cli_start.py base=/path/src,new=/path/src N -m shapeverify inspect panel.svm scan.ply --tolerance 0.2 --json r.json
"""
import os, resource, subprocess, sys, statistics, json
trees = dict(a.split("=") for a in sys.argv[1].split(","))
n = int(sys.argv[2]); cmd = sys.argv[3:]
py = sys.executable
res = {k: [] for k in trees}
loads = []
def run(src):
    env = dict(os.environ); env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPATH"] = src; env["SHAPEVERIFY_WORKER"] = "0"; env["COLUMNS"] = "120"
    b = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([py] + cmd, env=env, cwd=os.environ.get("WORK", "/tmp/cli8w"), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    a = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert p.returncode in (0, 1, 3), p.stderr[-2000:]
    return a.ru_utime - b.ru_utime + a.ru_stime - b.ru_stime
for k, src in trees.items(): run(src)   # untimed
for i in range(n):
    loads.append(os.getloadavg()[0])
    for k, src in trees.items(): res[k].append(run(src))
for k, v in res.items():
    print(f"{k}: median {statistics.median(v):.3f} range {min(v):.3f}-{max(v):.3f}  {[round(x,2) for x in v]}")
print("load", [round(x,1) for x in loads])
