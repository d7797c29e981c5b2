"""The ``robodepth`` command line.

Commands stay thin: they parse and validate options, then call the library modules.
Every expected failure is raised as :class:`UserError` (or a ``ValueError``/``OSError``
subclass caught here) and printed as one line, with a non-zero exit and no traceback.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from . import __version__


class UserError(click.ClickException):
    """A problem with the user's input: printed as ``robodepth: error: <message>``, exit 2."""

    exit_code = 2

    def show(self, file=None):
        click.echo(f"robodepth: error: {self.format_message()}", err=True)


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="robodepth")
def main():
    """Build the RoboDepth robustness benchmark datasets: KITTI-C, NYUDepth2-C and KITTI-S.

    \b
    Quick look at the corruptions:
      robodepth list
      robodepth preview frame.png --out sheet.png
    Build a dataset:
      robodepth build kitti-c --root KITTI_RAW --out KITTI_C
      robodepth verify KITTI_C
    """


# --- corruption commands (list, corrupt, preview) ---

# --- build commands (build, verify) ---

# --- style commands (stylize) ---

# --- score command ---


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
