"""The speed measurements (``make bench``). Run them as modules from the repository root,
``python -m bench.build [options]``: the root is then on the import path, so the checkout's
``robodepth_cli`` is what gets measured and the test suite's tree builders import as
``tests.helpers.trees``, with no edits of ``sys.path``."""
