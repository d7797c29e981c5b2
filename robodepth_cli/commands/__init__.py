"""The ``robodepth`` commands, one module per command family.

Each module defines click commands that parse options and call the library; it imports
only click and numpy at import time (``robodepth --help`` stays fast and never loads numba
or torch). A command raises :class:`robodepth_cli.errors.RobodepthError` for anything the
user can fix; :mod:`robodepth_cli.cli` turns it into one line and exit status 2. A new
command is a new module here plus one entry in :data:`COMMANDS`.
"""

from __future__ import annotations

from .build import build_command, verify_command
from .challenge import challenge_command
from .corrupt import corrupt_command, list_command, preview_command
from .evaluate import evaluate_command
from .export import export_command
from .gt import gt_command
from .predict import predict_command
from .report import report_command
from .run import run_command
from .score import score_command
from .selftest import selftest_command
from .stats import stats_command
from .stylize import stylize_command

COMMANDS = (run_command, list_command, corrupt_command, preview_command, build_command, verify_command,
            stylize_command, score_command, predict_command, evaluate_command, gt_command,
            report_command, stats_command, export_command, selftest_command, challenge_command)
