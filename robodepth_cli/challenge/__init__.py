"""``robodepth challenge``: the benchmark run as a challenge with a hidden test set.

- :mod:`.draw`: the seeded draw of (source frame, corruption, level) per image;
- :mod:`.build`: the public folder (anonymous images, their order, a README) and the private
  one (ground truth, key) made from a build;
- :mod:`.submission`: reading an upload safely (zip, npy, npz; bounded sizes, no pickle);
- :mod:`.resize`: scikit-image's ``resize`` as the official evaluator calls it, in numpy;
- :mod:`.scoring`: the official per-image metrics and the breakdowns the key allows;
- :mod:`.page`: ``detailed_results.html``;
- :mod:`.server`: the Codabench scoring program's entry point;
- :mod:`.bundle`: the Codabench competition bundle.

:mod:`.layout`, :mod:`.submission`, :mod:`.resize`, :mod:`.scoring`, :mod:`.page` and
:mod:`.server` import only numpy, the standard library and the package's ``errors``,
``benchmarks`` and ``evaluation.protocols``: the bundle's scoring program is these files,
copied, and runs on an image with nothing but Python and numpy.
"""
