"""The one exception type handeye raises for bad input.

Every user-facing failure is a :class:`HandEyeError`: a ``ValueError`` subclass whose
message has the form ``<what> (<where>): <how to fix>``, so the CLI can print it as one
line and exit with code 2.
"""
from __future__ import annotations


class HandEyeError(ValueError):
    """Bad input or an unsolvable problem, with a message that says how to fix it.

    Parameters
    ----------
    what:
        What is wrong, e.g. ``"unknown topic '/pose'"``.
    where:
        The file, topic, line or argument it concerns (may be empty).
    fix:
        How the user can fix it (may be empty).
    """

    def __init__(self, what: str, where: str = "", fix: str = "") -> None:
        self.what, self.where, self.fix = what, where, fix
        text = what
        if where:
            text += f" ({where})"
        if fix:
            text += f": {fix}"
        super().__init__(text)
