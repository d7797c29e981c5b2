"""The ``robodepth`` command line: the group, and the one place where a refusal becomes a
message.

Every command lives in :mod:`robodepth_cli.commands`. Anything the user can fix is raised
there or in the library as a :class:`~robodepth_cli.errors.RobodepthError`; the group
prints it as ``robodepth: error: <message>`` and exits with status 2, with no traceback.
"""

from __future__ import annotations

import sys

import click

from . import __version__
from .commands import COMMANDS
from .errors import RobodepthError


class UserError(click.ClickException):
    """A refusal as click shows it: ``robodepth: error: <message>``, exit 2."""

    exit_code = 2

    def show(self, file=None):
        click.echo(f"robodepth: error: {self.format_message()}", err=True)


class _Group(click.Group):
    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except RobodepthError as exc:
            raise UserError(str(exc)) from None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
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
    Evaluate a model on it (predictions from the open_dataset API) and score it:
      robodepth evaluate KITTI_C --pred PRED --score
      robodepth score results.csv --benchmark kitti-c
    """


for _command in COMMANDS:
    main.add_command(_command)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
