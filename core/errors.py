"""The one exception type the command line turns into a one-line message, and warnings.

Warnings are printed `glint: warning: <message>` on stderr. A warning that repeats per
object, material or camera (a zero-area triangle in 31 objects) gives a `WarningKind`:
inside a `summarised()` block such warnings are collected and printed when the block ends,
one line per kind with a count and the first few names, so 55 lines about flat meshes
become two. Outside any block, or with `summarised(verbose=True)` (`--verbose`), every
warning prints at once, as one line each. Warnings without a kind always print at once.

`summarised()` yields a `WarningRecord` of everything warned inside it (each warning,
summarised or not), which is how the loader learns which glTF features it ignored
(`warn(..., ignored=...)` -> `Scene.ignored_features`). The collector is per process:
warn with a kind from the main process only (bake workers would keep theirs).
"""
from __future__ import annotations

import sys
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Iterable, Iterator, Mapping

# Names a summary line lists before "... and N more": enough to find the first
# offenders in the scene, few enough to stay one line.
SUMMARY_NAMES = 3


class GlintError(Exception):
    """A problem with the user's input or environment, worded for the user.

    The command line prints `glint: <message>` and exits non-zero; with
    `--debug` it shows the traceback too. Raise it with a message that names the
    file, object or option at fault and, where there is one, the fix.
    """


def one_line(e: BaseException) -> str:
    """An exception's message on one line (whitespace runs as one space), or its type's name when it
    has none: for the detail a GlintError quotes from a library's exception."""
    return " ".join(str(e).split()) or type(e).__name__


@dataclass(frozen=True)
class WarningKind:
    """A warning that repeats per subject (object, material, camera), summarised in one line.

    `summary` is the line's text for two or more subjects, formatted with `n` (how many)
    and the sum of each of the warnings' `counts`, e.g. "{n} objects have zero-area
    triangles ({dropped:,} of their {triangles:,} triangles dropped)". Kinds are compared
    by value, so a module-level constant is the usual way to define one.
    """

    summary: str


@dataclass(frozen=True)
class Warned:
    """One warning as given to `warn`."""

    message: str
    kind: WarningKind | None = None
    subject: str | None = None
    detail: str | None = None
    counts: Mapping[str, int] = field(default_factory=dict)
    ignored: Mapping[str, int] = field(default_factory=dict)


@dataclass(eq=False)  # identity: nested blocks' records must never compare equal (_open.remove)
class WarningRecord:
    """Every warning given inside one `summarised()` block, in order."""

    warnings: list[Warned] = field(default_factory=list)

    def ignored_features(self) -> dict[str, int]:
        """{feature: how many materials, objects, cameras or uses} of what the warnings
        said glint ignores (their `ignored`), in the order first warned about."""
        out: dict[str, int] = {}
        for w in self.warnings:
            for feature, count in w.ignored.items():
                out[feature] = out.get(feature, 0) + count
        return out


_verbose = False
_quiet = 0  # > 0 inside quiet()
_open: list[WarningRecord] = []
_pending: dict[WarningKind, list[Warned]] = {}


def warn(message: str, kind: WarningKind | None = None, subject: str | None = None, *,
         detail: str | None = None, counts: Mapping[str, int] | None = None,
         ignored: Iterable[str] | Mapping[str, int] = ()) -> None:
    """A recoverable problem: printed to stderr (or, with a kind, summarised), the work goes on.

    `subject`: the object, material or camera it is about, named in the summary, followed by
    `detail` in parentheses when given; `counts`: numbers the kind's summary adds up;
    `ignored`: the glTF features the warning says glint ignores (names, each counting once,
    or {name: count}), kept in the enclosing `summarised()` blocks' records.
    """
    if _quiet:
        return
    if not isinstance(ignored, Mapping):
        ignored = {name: 1 for name in ignored}
    item = Warned(message, kind, subject, detail, dict(counts or {}), dict(ignored))
    for record in _open:
        record.warnings.append(item)
    if kind is None or _verbose or not _open:
        _print(message)
    else:
        _pending.setdefault(kind, []).append(item)


@contextmanager
def summarised(verbose: bool | None = None) -> Iterator[WarningRecord]:
    """Collect warnings with a kind until the block ends, then print one line per kind.

    The summaries are printed however the block ends (an error or Ctrl-C included), so
    nothing warned is lost; a nested block prints what is pending when it ends (the end of
    loading, of a bake). `verbose`: print every warning as it comes instead, for the block
    and the blocks inside it (None: as the enclosing block does).
    """
    global _verbose
    was, record = _verbose, WarningRecord()
    if verbose is not None:
        _verbose = verbose
    _open.append(record)
    try:
        yield record
    finally:
        _open.remove(record)
        flush()
        _verbose = was


@contextmanager
def quiet() -> Iterator[None]:
    """Drop the warnings given inside (neither printed nor recorded): for trial runs whose
    warnings the real run that follows gives again (bake/edits.py tries each --set this way)."""
    global _quiet
    _quiet += 1
    try:
        yield
    finally:
        _quiet -= 1


def flush() -> None:
    """Print the summary of every kind collected so far, and forget them."""
    pending = list(_pending.items())
    _pending.clear()
    for kind, items in pending:
        for line in summary_lines(kind, items):
            _print(line)


def summary_lines(kind: WarningKind, items: list[Warned]) -> list[str]:
    """One line for the warnings of one kind; each message itself when fewer than two subjects."""
    subjects: dict[str, Warned] = {}
    for i, item in enumerate(items):
        subjects.setdefault(item.subject if item.subject is not None else f"\0{i}", item)
    if len(subjects) < 2:
        return [item.message for item in items]
    sums: dict[str, int] = {}
    for item in items:
        for key, value in item.counts.items():
            sums[key] = sums.get(key, 0) + value
    named = [(f"'{item.subject}'" if item.subject is not None else None, item.detail)
             for item in subjects.values()]
    names = [name + (f" ({detail})" if detail else "") for name, detail in named if name is not None]
    shown = names[:SUMMARY_NAMES]
    if len(names) > len(shown):
        shown.append(f"... and {len(names) - len(shown)} more")
    text = kind.summary.format(n=len(subjects), **sums)
    return [text + (": " + ", ".join(shown) if shown else "")]


def _print(message: str) -> None:
    print(f"glint: warning: {message}", file=sys.stderr)
