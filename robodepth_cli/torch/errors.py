"""The one error of :mod:`robodepth_cli.torch`."""

from __future__ import annotations

from ..errors import RobodepthError


class TorchAPIError(RobodepthError):
    """A bad argument to a transform or dataset of :mod:`robodepth_cli.torch`."""
