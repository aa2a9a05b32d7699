"""Exceptions of the structural package (each subclasses a built-in)."""


class ModelError(ValueError):
    """A structural model is inconsistent (unknown ids, bad shapes, bad values)."""


class DimensionError(ValueError):
    """An array has the wrong shape."""


class ReductionError(ValueError):
    """Model reduction cannot proceed (singular matrices, too many modes...)."""
