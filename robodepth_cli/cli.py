"""The ``robodepth`` command line: the group, and the one place where a refusal becomes a
message.

Every command lives in :mod:`robodepth_cli.commands`. Anything the user can fix is raised
there or in the library as a :class:`~robodepth_cli.errors.RobodepthError`; the group
prints it as ``robodepth: error: <message>`` and exits with status 2, with no traceback.

Interrupts are handled here too, the same way for every command: Ctrl-C (SIGINT) and
SIGTERM (a batch scheduler's end of time) stop the command with one line,
``robodepth: interrupted; <what was kept>``, and exit status 130. Outputs are written
atomically, so nothing is left half-written; the line says which outputs are there
(:func:`robodepth_cli.commands.common.interrupt_note`).
"""

from __future__ import annotations

import signal
import sys

import click

from . import __version__
from .commands import COMMANDS
from .commands.common import ARGV, interrupt_note
from .errors import RobodepthError

INTERRUPTED = 130  # the shell's status for a SIGINT death; used for SIGTERM too


class UserError(click.ClickException):
    """A refusal as click shows it: ``robodepth: error: <message>``, exit 2."""

    exit_code = 2

    def show(self, file=None):
        click.echo(f"robodepth: error: {self.format_message()}", err=True)


class _Group(click.Group):
    def parse_args(self, ctx, args):
        ctx.meta[ARGV] = list(args)  # the command as typed, for messages that repeat it
        return super().parse_args(ctx, args)

    def invoke(self, ctx):
        previous = _stop_on_sigterm()
        try:
            return super().invoke(ctx)
        except RobodepthError as exc:
            raise UserError(str(exc)) from None
        except (KeyboardInterrupt, click.Abort):
            click.echo(f"robodepth: interrupted; {interrupt_note(ctx.meta)}", err=True)
            raise click.exceptions.Exit(INTERRUPTED) from None
        finally:
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)


def _stop_on_sigterm():
    """Make SIGTERM stop a command as Ctrl-C does (cleanly, through the same handler);
    the previous handler, or None where none can be set (not the main thread)."""
    try:
        return signal.signal(signal.SIGTERM, _interrupt)
    except ValueError:
        return None


def _interrupt(signum, frame):
    raise KeyboardInterrupt


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
    Run a model on every variant, evaluate it and score it:
      robodepth predict KITTI_C --model monodepth2:MODEL_DIR --out PRED
      robodepth evaluate KITTI_C --pred PRED --score
      robodepth score results.csv --benchmark kitti-c

    Ctrl-C or SIGTERM stops any command with one line saying what was kept (every output
    file is written whole or not at all), exit status 130.
    """


for _command in COMMANDS:
    main.add_command(_command)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
