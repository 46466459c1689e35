"""Atomic writes: all-or-nothing, and the file mode a plain open() would give."""
import os

import pytest

from dnarod.core.io import atomic_path, write_text_atomic


def test_atomic_write_mode_and_failure_leaves_old_file(tmp_path):
    p = tmp_path / "out.txt"
    write_text_atomic(p, "first")
    umask = os.umask(0)
    os.umask(umask)
    assert (p.stat().st_mode & 0o777) == (0o666 & ~umask)
    with pytest.raises(RuntimeError):
        with atomic_path(p) as tmp:
            open(tmp, "w").write("half")
            raise RuntimeError("crash mid-write")
    assert p.read_text() == "first"
    assert [f.name for f in tmp_path.iterdir()] == ["out.txt"]
