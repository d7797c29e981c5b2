"""The speed measurements (``make bench``). Run them as modules from the repository root,
``python -m bench.build [options]``: the root is then on the import path, so the checkout's
``robodepth_cli`` is what gets measured and the test suite's tree builders import as
``tests.helpers.trees``, with no edits of ``sys.path``."""

import os
import platform


def cpu_name() -> str:
    """The CPU's model name (Linux's /proc/cpuinfo, else what the platform says), printed
    beside each figure: machines differ 2x per core, so a time alone says little."""
    if os.path.exists("/proc/cpuinfo"):
        with open("/proc/cpuinfo") as f:
            name = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), "")
        if name:
            return name
    return platform.processor()
