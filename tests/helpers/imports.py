"""Which heavy libraries a command imports: the test that keeps each optional library out of
the commands that do not need it."""

from __future__ import annotations

import subprocess
import sys

_MARK = "imported:"


def imported_by_command(argv, modules, *, preload=(), stdout_has: str = "") -> list[str]:
    """Run ``robodepth ARGV`` in a fresh interpreter, after importing the ``preload`` modules;
    it must succeed (and print ``stdout_has``). Returns, sorted, those of ``modules`` it
    imported (a name counts with its submodules: ``dask`` covers ``dask.array``)."""
    code = ("".join(f"import {m}\n" for m in preload) + "import sys; from robodepth_cli.cli import main\n"
            "try:\n"
            f"    main({[str(a) for a in argv]!r})\n"
            "except SystemExit as e:\n"
            "    assert not e.code, e.code\n"
            f"names = {sorted(modules)!r}\n"
            "seen = sorted(n for n in names if any(m == n or m.startswith(n + '.') for m in sys.modules))\n"
            f"print({_MARK!r} + ','.join(seen), file=sys.stderr)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert stdout_has in res.stdout, res.stdout
    line = res.stderr.strip().splitlines()[-1]
    assert line.startswith(_MARK), res.stderr
    return [n for n in line[len(_MARK):].split(",") if n]
