"""Atomic writes: a file is either its old self or wholly new, never half-written.

Everything glint writes for a user (images, bake manifests, stats, bench reports, plots) goes
through `atomic_path`: the writer fills a temporary file beside the target (same folder, so the
rename cannot cross file systems; same extension, so writers that pick a format from it work),
which is renamed over the target only when the writer finished without an error. The temporary
file is named `.STEM.PID.tmp.EXT` (PID the writing process); one left by a process that was killed
(SIGKILL, a power cut) is removed by the next write of the same target, once that process is gone.
"""
from __future__ import annotations

import os
import re
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from glint.core.errors import GlintError


@contextmanager
def atomic_path(path: Path | str) -> Iterator[Path]:
    """Yield a temporary path beside `path`; on success rename it to `path`, on failure remove it.
    An OSError becomes a GlintError that names `path`."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    _remove_dead_temporaries(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as e:
        raise GlintError(f"cannot write {path}: {e.strerror or e}") from e
    finally:
        if tmp.exists():
            tmp.unlink()


def atomic_write_text(path: Path | str, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def pid_alive(pid: int) -> bool:
    """Whether process `pid` exists (on this machine); when in doubt, True."""
    if pid <= 0:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OSError, OverflowError):
        return True
    return True


def dead_leftovers(path: Path, *patterns: re.Pattern) -> list[tuple[os.DirEntry, re.Match]]:
    """The entries beside `path` (in its folder) whose name fully matches one of `patterns` and whose
    process (the pattern's first group, a pid) is gone, with the match: what a killed glint left."""
    try:
        entries = list(os.scandir(path.parent if str(path.parent) else "."))
    except OSError:
        return []
    found = []
    for entry in entries:
        match = next(filter(None, (p.fullmatch(entry.name) for p in patterns)), None)
        if match and not pid_alive(int(match.group(1))):
            found.append((entry, match))
    return found


def _remove_dead_temporaries(path: Path) -> None:
    """Remove `path`'s temporary files (`.STEM.PID.tmp.EXT`, exactly) whose process is gone."""
    pattern = re.compile(rf"\.{re.escape(path.stem)}\.(\d+)\.tmp{re.escape(path.suffix)}")
    for entry, _ in dead_leftovers(path, pattern):
        if entry.is_file(follow_symlinks=False):
            try:
                os.unlink(entry.path)
            except OSError:
                pass
