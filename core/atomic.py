"""Atomic writes: a file is either its old self or wholly new, never half-written.

Everything glint writes for a user (images, bake manifests, stats, bench reports, plots) goes
through `atomic_path`: the writer fills a temporary file beside the target (same folder, so the
rename cannot cross file systems; same extension, so writers that pick a format from it work),
which is renamed over the target only when the writer finished without an error.
"""
from __future__ import annotations

import os
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
