"""Exceptions of the FE package: every failure says what was wrong and what to do."""


class FEError(Exception):
    """Base class of errors raised by the FE solver."""


class MeshError(FEError, ValueError):
    """An invalid mesh or mesh layout (bad subdivision, non-matching interface pair, ...)."""


class SensorError(FEError, ValueError):
    """A sensor that cannot be placed: outside the specimen, or on an interface."""


class SpecError(FEError, ValueError):
    """An invalid scenario spec or parameter value (unknown name, outside physical limits)."""


class SolverError(FEError):
    """The linear solver failed (singular stiffness: a missing support or a zero stiffness)."""


class ConstraintError(SpecError):
    """Parameter values, or a sampling box, that violate a constraint between parameters (e.g. a
    tensile strength above the Coulomb apex of the joints); ``violations`` holds the
    :class:`fe.admissibility.Violation` objects with their remedies."""

    def __init__(self, message, violations=()):
        super().__init__(message)
        self.violations = tuple(violations)
