"""The error every model adapter raises, in a module of its own: the adapters import it
without importing the package, whose ``load_model`` imports them (a circle otherwise)."""

from __future__ import annotations

from ..errors import RobodepthError


class ModelError(RobodepthError):
    """A model spec, checkpoint or model output that cannot be used (one line)."""
