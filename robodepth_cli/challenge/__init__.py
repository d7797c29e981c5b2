"""``robodepth challenge``: the benchmark run as a challenge with a hidden test set
(docs/challenge.md).

:mod:`.layout`, :mod:`.submission`, :mod:`.resize`, :mod:`.scoring`, :mod:`.page` and
:mod:`.server` import only numpy, the standard library and the package's ``errors``,
``benchmark_facts`` and ``evaluation.protocols``: the bundle's scoring program is these files,
copied, and runs on an image with nothing but Python and numpy."""
