"""Files that are not LCM logs, and what the Python tools must say about each (test_cli:
hapticloth-replay, test_plot: hapticloth-plot)."""

from __future__ import annotations

from pathlib import Path

import pytest

# The file's content (None: there is no file) and the words of the error.
NOT_LCM_LOGS = pytest.mark.parametrize("content, words", [
    (None, "cannot open as an LCM log (no such file)"),
    (b"", "empty, not an LCM log"),
    (b"time,finger,x,y,z\n0.5,0,0,0,0\n", "not an LCM log"),
    (bytes(range(256)) * 8, "not an LCM log"),
])


def not_lcm_log(tmp_path: Path, content: bytes | None) -> Path:
    """tmp_path/in.lcm holding `content` (not written for None)."""
    log = tmp_path / "in.lcm"
    if content is not None:
        log.write_bytes(content)
    return log
