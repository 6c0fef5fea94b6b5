"""Exceptions and warnings raised by :mod:`mbn`.

Every error that bad user input can cause is an :class:`MbnInputError`; the command line turns it
into one line on stderr and exit status 2.
"""

from __future__ import annotations


class MbnInputError(ValueError):
    """Input that :mod:`mbn` cannot use: wrong shape, non-finite value, malformed file, ...

    The message names the parameter, or the file and line, that is wrong.
    """


class UnstableStepError(MbnInputError):
    """An integration step too large for the stiffness of a network."""


class MbnWarning(UserWarning):
    """A warning of :mod:`mbn` (the command line prints it as one line ``mbn: warning: ...``)."""


class UnstableStepWarning(MbnWarning, RuntimeWarning):
    """An integration step that is probably too large for the stiffness of a network."""
