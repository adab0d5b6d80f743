"""Regenerates the cached Mitsuba 3 references in tests/data/mitsuba/ (tests/mitsuba_cache.py; run
from the checkout after a change that makes them stale; about 6 minutes on a 2-core machine):

    python3 tests/data/make_mitsuba_cache.py [PYTEST ARGS]

It runs the tests that read the cache (mitsuba_cache.CACHED_TESTS, or the pytest arguments given)
with GLINT_MITSUBA_CACHE=write: each test renders its reference with Mitsuba, exactly as without a
cache, and writes it with its key before it compares (so a failing comparison still leaves a true
reference). Then it lists the files in tests/data/mitsuba/ that no test wrote (left from a renamed
or removed case: delete them) and the directory's size.
"""
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(HERE.parent))


def main() -> int:
    import mitsuba_cache
    import pytest

    start = time.time()
    os.chdir(ROOT)
    os.environ[mitsuba_cache.ENV] = "write"
    code = pytest.main([*(sys.argv[1:] or mitsuba_cache.CACHED_TESTS), "-q", "-p", "no:cacheprovider"])
    files = sorted(mitsuba_cache.DATA.glob("*.npz"))
    unused = [f.name for f in files if f.stat().st_mtime < start]
    print(f"{len(files)} files, {sum(f.stat().st_size for f in files) / 1024:.0f} KiB in {mitsuba_cache.DATA}")
    if unused and not sys.argv[1:]:
        print("not written by any test (delete them):", " ".join(unused))
    return int(code)


if __name__ == "__main__":
    sys.exit(main())
