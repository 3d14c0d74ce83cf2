"""Typed errors raised when a message or an array breaks the interface contract.

Every error is a ``ValueError`` (through :class:`InterfaceError`), so a node can catch the whole family with
one ``except InterfaceError`` and still tell the cases apart when it needs to.
"""


class InterfaceError(ValueError):
    """Base class: a message or an array does not follow the SMM interface contract."""


class JointNameError(InterfaceError):
    """Joint names are unknown, missing or duplicated (the plant has exactly ``alpha`` and ``beta``)."""


class ArrayLengthError(InterfaceError):
    """An array has the wrong length or shape (per-joint arrays are shape (2,), a reference (3, 2))."""


class NonFiniteError(InterfaceError):
    """A value is NaN or infinite; such a value is never published nor accepted."""


class LayoutError(InterfaceError):
    """A ``MultiArrayLayout`` is inconsistent: dimension count, labels, sizes, strides or ``data_offset``."""


class StampError(InterfaceError):
    """A stamp is negative, not an integer, or outside the range of ``builtin_interfaces/Time``."""
