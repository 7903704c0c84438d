"""Assemble benchmarks/RESULTS.md from the per-benchmark result files (results_*.md).

Each benchmark script writes its own results_<topic>.md with the command that produced it; this
script puts them together in the order of the data flow.  What is measured or written by hand
beside a benchmark goes in results_<topic>_notes.md (a benchmark's --out rewrites its own file),
so RESULTS.md is always what this script makes. Run: .venv/bin/python benchmarks/collect_results.py
"""

from __future__ import annotations

import datetime
import platform
from pathlib import Path

HERE = Path(__file__).resolve().parent
ORDER = ["nurbs", "cad_import", "closest", "closest_notes", "prepare", "register", "global",
         "independent", "symmetric", "impeller_starts", "turned", "inspection", "coldstart", "rays", "measure", "phase",
         "fitting", "service"]


def main() -> None:
    files = {p.stem.removeprefix("results_"): p for p in HERE.glob("results_*.md")}
    topics = [t for t in ORDER if t in files] + sorted(set(files) - set(ORDER))
    parts = [
        "# Benchmark results",
        "",
        "Each section was written by the benchmark named in it, which runs shapeverify and a named peer "
        "in the same process and prints the ratio. Machine: 2 cores, 24 GB, shared with other work "
        "(wall times are noisy; where a section gives CPU time, that is the fairer single-core figure). "
        f"Assembled {datetime.date.today().isoformat()} on Python {platform.python_version()} by "
        "`.venv/bin/python benchmarks/collect_results.py`.",
        "",
    ]
    for t in topics:
        text = files[t].read_text().strip()
        if not text.startswith("#"):
            text = f"## {t}\n\n{text}"
        else:
            text = "#" + text if text.startswith("# ") else text
        parts += [text, ""]
    (HERE / "RESULTS.md").write_text("\n".join(parts))
    print(f"wrote {HERE / 'RESULTS.md'} from {len(topics)} result files: {', '.join(topics)}")


if __name__ == "__main__":
    main()
