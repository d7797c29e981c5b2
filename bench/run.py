"""`make bench` (``python -m bench.run``): run every benchmark script under bench/ that
exists, one after another.

Each runs in its own interpreter with its default settings (so each sets its own thread
limits before importing numpy); run a script directly to pass it options. Each script
prints its ratios against the previous way measured in the same run; the machine's load
average is printed before each, since other processes slow everything down. Exits
non-zero if any script fails.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SCRIPTS = ("corruptions.py", "exact.py", "depth.py", "png.py", "build.py", "stylize.py", "cluster.py", "gt.py",
           "evaluate.py", "source_hash.py", "large.py", "severity_size.py", "predict.py", "torch_engine.py",
           "export.py", "frames.py", "codec.py", "run_cmd.py", "challenge.py", "pixels.py", "compile.py")


def main() -> int:
    failed = []
    for script in SCRIPTS:
        path = HERE / script
        if not path.is_file():
            continue
        load = os.getloadavg()
        print(f"=== bench/{script} (load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} on "
              f"{os.cpu_count()} CPUs)", flush=True)
        # As a module from the repository root: see bench/__init__.py.
        if subprocess.run([sys.executable, "-m", f"bench.{path.stem}"], cwd=HERE.parent).returncode != 0:
            failed.append(script)
        print(flush=True)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
