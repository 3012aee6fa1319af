"""Errors raised on bad input: they name the file, the field and what was expected."""

from __future__ import annotations

from os import PathLike


class InputError(ValueError):
    """Bad input data: a file, field or value that is not what the toolkit expects.

    The message reads ``FILE:LINE: FIELD: what is wrong (what was expected)`` with the parts that
    are known, so a user can find the problem without a traceback.
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | PathLike[str] | None = None,
        field: str | None = None,
        line: int | None = None,
    ) -> None:
        self.path = None if path is None else str(path)
        self.field = field
        self.line = line
        self.reason = message
        super().__init__(self._format())

    def _format(self) -> str:
        where = ""
        if self.path is not None:
            where = self.path if self.line is None else f"{self.path}:{self.line}"
        elif self.line is not None:
            where = f"line {self.line}"
        parts = [p for p in (where, self.field) if p]
        return ": ".join([*parts, self.reason])


class OutOfRangeError(ValueError):
    """A query outside the valid range of some data (e.g. a time outside a trajectory)."""
