"""A/B of the default worker (bench_cli.measure_auto: 1st/2nd/3rd command and the preload), source
trees interleaved, one round each at a time.  Inputs in WORK (default /tmp/cli8w).
Run: python benchmarks/ab_cli_worker.py base=/path/src,new=/path/src ROUNDS
A tree may name its own prepared model (base=/path/src:panel.svm,new=/path/src:panel_new.svm):
it is linked as panel.svm in the tree's work directory.
"""
import sys, os, json
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_cli
trees = dict(a.split("=") for a in sys.argv[1].split(","))
svm = {k: (v.split(":") + ["panel.svm"])[1] for k, v in trees.items()}
trees = {k: v.split(":")[0] for k, v in trees.items()}
rounds = int(sys.argv[2])
argv = [sys.executable, "-m", "shapeverify", "inspect", "panel.svm", "scan.ply", "--tolerance", "0.2", "--json", "r.json"]
res = {k: [] for k in trees}
for r in range(rounds):
    for k, src in trees.items():
        env = bench_cli._env(); env["PYTHONPATH"] = src
        work = Path(os.environ.get("WORK", "/tmp/cli8w")) / f"w_{k}"; work.mkdir(exist_ok=True)
        for f, g in (("panel.svm", svm[k]), ("scan.ply", "scan.ply")):
            if not (work / f).exists(): os.symlink(Path(os.environ.get("WORK", "/tmp/cli8w")) / g, work / f)
        out = bench_cli.measure_auto(argv, work, env, 1)
        res[k].append((out["first"]["median"], out["second"]["median"], out["third"]["median"], out["preload"], out["first_in_worker"], out["load"]))
        print(k, [round(x, 3) if isinstance(x, float) else x for x in res[k][-1]], flush=True)
import statistics
for k, v in res.items():
    print(k, "first", round(statistics.median(x[0] for x in v), 3), "second", round(statistics.median(x[1] for x in v), 3),
          "third", round(statistics.median(x[2] for x in v), 3), "preload", round(statistics.median(x[3] for x in v), 3))
