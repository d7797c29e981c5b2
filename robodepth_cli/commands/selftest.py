"""``robodepth selftest``: is this install making the reference bytes?"""

from __future__ import annotations

import sys
import time

import click


@click.command("selftest")
def selftest_command():
    """Build the small fixtures robodepth ships, with every kind of variant, and compare
    each output with the reference recorded on the locked install.

    \b
    The builds: the 18 corruptions and the six depth-aware ones at levels 1-5 and 2.5, a
    chain, the corruptions over time on a three-frame sequence, and KITTI-S through a
    small AdaIN with seeded random weights (h264_crf, h265_crf and bit_error need PyAV,
    KITTI-S torch: without one, its outputs are skipped and a line says so). Every output must have the
    reference's bytes, except KITTI-S's stylised images, which may differ by 1 grey level
    (torch's CPU kernels are not bit-exact across CPUs). About 10-30 s on 2 cores.

    Prints one line when everything matches (exit status 0), after a warning naming each
    library that decides pixels whose installed version is not the lock's, if any. When an
    output differs, names each variant that differs, with its largest grey-level difference,
    and those libraries; exit status 1. Exit status 2: it could not run.
    """
    import contextlib
    import io
    import tempfile
    from pathlib import Path

    from ..errors import RobodepthError
    from ..selftest.check import OPTIONAL, read_reference, run

    ref = read_reference()
    start = time.monotonic()
    try:
        work_dir = tempfile.TemporaryDirectory(prefix="robodepth-selftest-")
    except OSError as exc:
        raise RobodepthError(f"cannot create a temporary folder in {tempfile.gettempdir()} ({exc}); "
                             f"set TMPDIR to a writable folder") from None
    with work_dir as work, contextlib.redirect_stderr(io.StringIO()):  # the builds' own notes
        outcome = run(Path(work), ref)
    seconds = time.monotonic() - start
    for name in outcome.skipped:
        click.echo(f"skipped {OPTIONAL[name]} is not installed")
    versions = f"installed versions other than the lock: {'; '.join(outcome.versions)}"
    if outcome.ok:
        if outcome.versions:
            click.echo(f"warning: {versions}; they make the reference bytes here", err=True)
        click.echo(f"selftest: all {outcome.checked} outputs match the reference (KITTI-S within 1 grey level), "
                   + ("versions not as locked" if outcome.versions else "versions as locked")
                   + f", in {seconds:.0f} s")
        return
    for variant, result in outcome.failed.items():
        click.echo(f"{variant}: {result.text()}")
    if outcome.versions:
        click.echo(versions)
    bad = sum(r.differ + len(r.not_built) for r in outcome.failed.values())
    click.echo(f"selftest: {bad} of {outcome.checked} outputs differ from the reference"
               + ("; this is not the locked install" if outcome.versions else ""), err=True)
    sys.exit(1)
