"""The scoring program: what Codabench's compute worker runs, and what ``robodepth
challenge score`` and ``check`` call.

On Codabench the worker mounts the phase's reference data at ``/app/input/ref``, the
participant's upload (already unzipped) at ``/app/input/res`` and an empty
``/app/output``, and runs ``metadata.yaml``'s command in ``/app/program``; it reads
``/app/output/scores.json`` and shows ``detailed_results.html`` and the program's stderr.
A refused submission is one line on stderr and exit status 1, and no ``scores.json``.
"""

from __future__ import annotations

import json
import os
import sys

from ..errors import RobodepthError
from . import layout
from .scoring import open_reference, score
from .submission import open_submission

DEFAULT_MAX_BYTES = 512 * 10 ** 6
SCORES = "scores.json"
DETAILS = "detailed_results.html"


def write_results(scores, out: str) -> dict:
    """Write ``scores.json`` and ``detailed_results.html`` into ``out``; return the scores."""
    from .page import detailed_results

    flat = scores.flat()
    os.makedirs(out, exist_ok=True)
    for name, text in ((SCORES, json.dumps(flat, indent=1, sort_keys=True) + "\n"),
                       (DETAILS, detailed_results(scores))):
        tmp = os.path.join(out, f".{name}.tmp")
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, os.path.join(out, name))
    return flat


def score_folder(submission: str, reference: str, out: str | None,
                 max_bytes: int = DEFAULT_MAX_BYTES):
    """Score ``submission`` against the reference folder; write the results into ``out``
    when given. Returns the :class:`.scoring.Scores`."""
    ref = open_reference(reference)
    with open_submission(submission, ref.ids, max_bytes, scratch=out) as sub:
        scores = score(sub, ref)
    if out is not None:
        write_results(scores, out)
    return scores


def check_folder(submission: str, public: str, max_bytes: int = DEFAULT_MAX_BYTES) -> tuple[str, int]:
    """Everything the server checks, offline: every map read and checked. Returns the
    submission's form and its number of maps."""
    layout.read_meta(public)
    ids = layout.read_list(public)
    with open_submission(submission, ids, max_bytes) as sub:
        n = sum(1 for _ in sub.maps())
        return sub.form, n


def main(argv=None) -> int:
    """``python score.py [INPUT OUTPUT]`` (Codabench: ``/app/input`` and ``/app/output``)."""
    argv = sys.argv[1:] if argv is None else argv
    input_dir = argv[0] if argv else "/app/input"
    output_dir = argv[1] if len(argv) > 1 else "/app/output"
    max_bytes = int(os.environ.get("ROBODEPTH_MAX_BYTES", DEFAULT_MAX_BYTES))
    try:
        scores = score_folder(os.path.join(input_dir, "res"), os.path.join(input_dir, "ref"),
                              output_dir, max_bytes)
    except RobodepthError as exc:
        print(f"submission refused: {exc}", file=sys.stderr)
        return 1
    except MemoryError:
        print("submission refused: out of memory while reading it", file=sys.stderr)
        return 1
    flat = scores.flat()
    print(" ".join(f"{m}={flat[m]:.4f}" for m in scores.metrics))
    return 0
