"""The one exception type the command line turns into a one-line message."""
import sys


class GlintError(Exception):
    """A problem with the user's input or environment, worded for the user.

    The command line prints `glint: <message>` and exits non-zero; with
    `--debug` it shows the traceback too. Raise it with a message that names the
    file, object or option at fault and, where there is one, the fix.
    """


def warn(message: str) -> None:
    """A recoverable problem: printed once to stderr, the work goes on."""
    print(f"glint: warning: {message}", file=sys.stderr)
