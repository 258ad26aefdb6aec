"""Exceptions that the command line turns into `error: ...` and exit code 2."""


class InputError(Exception):
    """Bad user input: a file, config value or argument that cannot be used.

    The message names the file (or option) and what is wrong, on one line.
    """


class MissingExtraError(InputError):
    """An optional extra is not installed; the message names the pip command."""

    def __init__(self, extra: str, package: str) -> None:
        super().__init__(
            f"{package} is not installed: run `pip install 'vtrack[{extra}]'`"
        )
