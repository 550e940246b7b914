"""Writing a file so that it is either complete or absent.

The content goes to a hidden file beside the target, with the same name ending (writers that
choose the format by the suffix, such as OpenCV's FileStorage, see the right one), and is
renamed over the target only once it is complete. A reader never sees a partial file, and a
write that fails leaves nothing behind and the old file, if any, untouched.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def temporary_sibling(path: Path) -> Path:
    """A fresh hidden file name in ``path``'s folder, ending like ``path``'s name."""
    return path.with_name(f".{uuid.uuid4().hex[:12]}-{path.name}")


@contextmanager
def atomic_file(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path to write; on leaving, rename it over ``path``.

    If the block raises, or the rename fails, the temporary file is removed and the
    exception propagates; ``path`` is then as it was.
    """
    path = Path(path)
    tmp = temporary_sibling(path)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
