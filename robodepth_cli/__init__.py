"""robodepth: build the RoboDepth robustness benchmark datasets."""

from .formats import RELEASE as __version__  # noqa: F401 (the release, kept with the formats)


def open_dataset(path, *, warn: bool = True):
    """Open a dataset directory written by ``robodepth build``, or its export (``robodepth
    export``: the same variants, images read with ``variant.read``): a
    :class:`~robodepth_cli.api.BuiltDataset` (:func:`robodepth_cli.api.open_dataset` says
    what is checked). The package's face joins the two readers, so that neither the build's
    reader (:mod:`robodepth_cli.api`) nor the stages above it depend on the export."""
    # Imported here, so that `import robodepth_cli` (and `robodepth --help`) stays light.
    from .api import open_dataset as open_build
    from .export.reader import opening

    return open_build(path, warn=warn, **opening(path))
