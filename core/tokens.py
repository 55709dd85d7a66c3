"""Whitespace-separated number streams with line numbers, for text reconstruction formats."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

from core.errors import InputError


class TokenReader:
    """Reads numbers one at a time from a text file, naming file and line in every error."""

    def __init__(self, path: str | Path, skip_comment_lines: bool = False) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError(f"{self.path}: no such file")
        try:
            text = self.path.read_text()
        except UnicodeDecodeError as err:
            raise InputError(f"{self.path}: not a text file ({err.reason})") from err
        self._tokens = self._tokenise(text, skip_comment_lines)
        self.line = 0

    @staticmethod
    def _tokenise(text: str, skip_comment_lines: bool) -> Iterator[tuple[str, int]]:
        for number, line in enumerate(text.splitlines(), start=1):
            if skip_comment_lines and line.lstrip().startswith("#"):
                continue
            for token in line.split():
                yield token, number

    def error(self, message: str) -> InputError:
        return InputError(f"{self.path}:{self.line}: {message}")

    def _next(self, what: str) -> str:
        try:
            token, self.line = next(self._tokens)
        except StopIteration:
            raise InputError(f"{self.path}: file ends early (after line {self.line}) while reading {what}") from None
        return token

    def int(self, what: str, minimum: int = 0) -> int:
        token = self._next(what)
        try:
            value = int(token)
        except ValueError:
            raise self.error(f"expected an integer for {what}, got {token!r}") from None
        if value < minimum:
            raise self.error(f"{what} must be >= {minimum}, got {value}")
        return value

    def floats(self, count: int, what: str) -> list[float]:
        values = []
        for _ in range(count):
            token = self._next(what)
            try:
                value = float(token)
            except ValueError:
                raise self.error(f"expected a number for {what}, got {token!r}") from None
            if not math.isfinite(value):
                raise self.error(f"{what} must be finite, got {token!r}")
            values.append(value)
        return values

    def expect_end(self) -> None:
        for token, line in self._tokens:
            self.line = line
            raise self.error(f"unexpected trailing data {token!r}")
