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

import os
import signal
import sys

INTERRUPTED = 130  # the shell's status for a SIGINT death; used for SIGTERM too


def _stopped_while_starting(signum, frame):
    # Before the group's own handler (imports take a while): nothing has been written yet.
    os.write(2, b"robodepth: interrupted; nothing was written\n")
    os._exit(INTERRUPTED)


def _stopped_at_the_end(signum, frame):
    # After the command's work and its last line, while the interpreter ends: the same
    # status as during the work, not the signal's own (143 for SIGTERM).
    try:
        sys.stdout.flush()  # os._exit would drop what is still buffered
    except (OSError, ValueError, RuntimeError):  # closed, or interrupted mid-write
        pass
    os.write(2, b"robodepth: interrupted as the command ended; what it wrote is complete\n")
    os._exit(INTERRUPTED)


if __name__ == "__main__" or os.path.basename(sys.argv[0]) in ("robodepth", "robodepth.exe"):
    # Run as the command, not imported: Ctrl-C and SIGTERM give exit 130 from the start.
    for _sig in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(_sig) in (signal.SIG_DFL, signal.default_int_handler):  # not ignored
            signal.signal(_sig, _stopped_while_starting)

import click  # noqa: E402

from . import __version__  # noqa: E402
from .commands import COMMANDS  # noqa: E402
from .commands.common import ARGV, interrupt_note  # noqa: E402
from .errors import RobodepthError, is_interrupt, note_interrupt  # noqa: E402


class UserError(click.ClickException):
    """A refusal as click shows it: ``robodepth: error: <message>``, exit 2."""

    exit_code = 2

    def show(self, file=None):
        click.echo(f"robodepth: error: {self.format_message()}", err=True)


class _Group(click.Group):
    def parse_args(self, ctx, args):
        ctx.meta[ARGV] = list(args)  # the command as typed, for messages that repeat it
        try:
            return super().parse_args(ctx, args)
        except click.UsageError as exc:
            raise _usage_error(exc, ctx) from None

    def invoke(self, ctx):
        note_interrupt(False)
        previous = _stop_on_sigterm()
        try:
            return super().invoke(ctx)
        except (KeyboardInterrupt, click.Abort):
            raise _interrupted(ctx) from None
        except Exception as exc:
            # Ctrl-C or SIGTERM in another exception's clothes (numba's SystemError around
            # the KeyboardInterrupt, a refusal raised while it propagated) is an interrupt.
            if is_interrupt(exc) and not isinstance(exc, (click.exceptions.Exit, click.ClickException)):
                raise _interrupted(ctx) from None
            if isinstance(exc, RobodepthError):
                raise UserError(str(exc)) from None
            if isinstance(exc, click.UsageError):  # a subcommand's options, as click parses them
                raise _usage_error(exc, ctx) from None
            raise
        finally:
            note_interrupt(False)  # handled: library code run after the command is not stopped
            for signum, handler in previous.items():
                # Run as the command: the interpreter still has to end after the last line.
                signal.signal(signum, _stopped_at_the_end if handler is _stopped_while_starting
                              else handler)


def _interrupted(ctx) -> click.exceptions.Exit:
    """Print the interrupt's line (what was kept) and give the exit to raise: status 130."""
    click.echo(f"robodepth: interrupted; {interrupt_note(ctx.meta)}", err=True)
    return click.exceptions.Exit(INTERRUPTED)


def _usage_error(exc: click.UsageError, group_ctx) -> click.ClickException:
    """click's refusal of the command line (a bad option value, a missing or unknown option)
    as every other refusal: ``robodepth: error: --flag: problem``, one line, exit 2, where
    click would print its usage block and ``Error: Invalid value for ...``."""
    if getattr(click.exceptions, "NoArgsIsHelpError", ()) and \
            isinstance(exc, click.exceptions.NoArgsIsHelpError):
        return exc  # a group called bare: its help, as click shows it
    command = " ".join(["robodepth", *_command_names(exc.ctx, group_ctx)])
    if isinstance(exc, click.MissingParameter):
        return UserError(f"{_param_name(exc)}: required; see {command} --help")
    if isinstance(exc, click.BadParameter):
        name = _param_name(exc)
        return UserError(f"{name}: {_sentence(exc.message)}" if name else _sentence(exc.message))
    return UserError(f"{_sentence(exc.format_message())}; see {command} --help")


def _command_names(ctx, group_ctx) -> list[str]:
    """The subcommands (``["gt", "kitti"]``) of the error's context, else (click's parser
    gives some errors none) of the command line as typed."""
    names: list[str] = []
    if ctx is not None and ctx.parent is not None:
        while ctx.parent is not None:
            names.insert(0, ctx.info_name)
            ctx = ctx.parent
        return names
    command = group_ctx.command
    for arg in group_ctx.meta.get(ARGV, []):
        if not isinstance(command, click.Group) or arg not in command.commands:
            break
        names.append(arg)
        command = command.commands[arg]
    return names


def _param_name(exc: click.BadParameter) -> str:
    """The flag as the user knows it (``--jobs``, not ``'--jobs' / '-j'``), or an
    argument's metavar (``DATASET_DIR``)."""
    param = exc.param
    if param is None:
        hint = exc.param_hint
        return hint if isinstance(hint, str) or hint is None else hint[0]
    if isinstance(param, click.Option):
        return next((o for o in param.opts if o.startswith("--")), param.opts[0])
    return param.human_readable_name


def _sentence(text: str) -> str:
    """click's message as a clause of ours: no final period, lower case first word
    ("Directory '/x' is a file." -> "directory '/x' is a file")."""
    text = text.strip().rstrip(".").replace(". (Did you mean", " (did you mean")
    if len(text) > 1 and text[0].isupper() and text[1].islower():
        text = text[0].lower() + text[1:]
    return text


def _stop_on_sigterm() -> dict:
    """Make SIGTERM stop a command as Ctrl-C does, and both through :func:`_interrupt`;
    the previous handlers (none where none can be set: not the main thread)."""
    previous = {}
    try:
        for signum in (signal.SIGINT, signal.SIGTERM):
            handler = signal.getsignal(signum)
            if signum == signal.SIGINT and handler not in (signal.default_int_handler,
                                                           _stopped_while_starting):
                continue  # ignored (started in the background), or someone else's
            previous[signum] = signal.signal(signum, _interrupt)
    except ValueError:
        return previous
    return previous


def _interrupt(signum, frame):
    # Noted as well as raised: a KeyboardInterrupt raised while compiled code (a numba
    # kernel) returns reaches its caller wrapped in another exception, which the handlers
    # that record an image's failure must not take for one (errors.is_interrupt).
    note_interrupt()
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
    Share it as Hugging Face parquet (or WebDataset tar) shards:
      robodepth export KITTI_C --format parquet --to KITTI_C_HF
    Run a model on every variant, evaluate it and score it:
      robodepth predict KITTI_C --model monodepth2:MODEL_DIR --out PRED
      robodepth evaluate KITTI_C --pred PRED --score
      robodepth score results.csv --benchmark kitti-c
    Or all of that in memory, without writing the dataset:
      robodepth run kitti-c --root KITTI_RAW --model monodepth2:MODEL_DIR --out results.csv
    Then the paper's tables and figures:
      robodepth report results.csv --out REPORT

    Ctrl-C or SIGTERM stops any command with one line saying what was kept (every output
    file is written whole or not at all), exit status 130.
    """


for _command in COMMANDS:
    main.add_command(_command)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
