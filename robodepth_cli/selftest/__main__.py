"""``python -m robodepth_cli.selftest --record`` (``make selftest-record``): the maintainer's
one way to write the selftest's reference, on the locked install."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from .check import DATA, SelftestError, absent, build_all, record, version_differences


def main(argv: list[str]) -> int:
    if argv != ["--record"]:
        print("usage: python -m robodepth_cli.selftest --record   (rewrites the selftest's "
              "reference; users run 'robodepth selftest')", file=sys.stderr)
        return 2
    problems = version_differences()
    problems += [f"{name} is not installed" for name in absent()]
    if problems:
        print(f"selftest --record: not the locked install ({'; '.join(problems)}); run make install "
              f"first", file=sys.stderr)
        return 2
    try:
        with tempfile.TemporaryDirectory(prefix="robodepth-selftest-") as work:
            build_all(Path(work))
            n = record(Path(work))
    except SelftestError as exc:
        print(f"selftest --record: {exc}", file=sys.stderr)
        return 2
    print(f"recorded {n} outputs into {DATA}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
