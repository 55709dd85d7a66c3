"""Errors raised for bad user input (files, arguments), reported by the command lines in one line."""


class InputError(ValueError):
    """An input file or argument is missing, malformed or inconsistent; the message names it."""
