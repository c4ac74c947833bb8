"""Domain exceptions of podkrig; the CLI turns them into one-line messages with a hint."""


class PodkrigError(Exception):
    """Base class of podkrig errors."""


class NotFittedError(PodkrigError, ValueError):
    """An estimator used before ``fit``."""


class StoreError(PodkrigError):
    """A snapshot or surrogate store that cannot be used (missing, corrupt, incompatible)."""


class SchemaError(StoreError):
    """A store written with an unknown or incompatible schema version."""


class InUseError(PodkrigError):
    """A file or folder held by another podkrig job (its lock file names the process)."""


class StoreInUseError(StoreError, InUseError):
    """A store held by another writer (its lock file names the process)."""


class IntegrityError(StoreError):
    """A file whose content does not match the checksums stored with it (damaged after writing)."""
