"""Where the tests find the C++ programs: the build directory of tools/setup
(HAPTICLOTH_BUILD_DIR, relative to the repository, default build/)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def build_dir() -> Path:
    build = Path(os.environ.get("HAPTICLOTH_BUILD_DIR", REPO / "build"))
    return build if build.is_absolute() else REPO / build


def program(name: str) -> Path:
    """The built program `name`; skips the test when it is not built."""
    exe = build_dir() / name
    if not (exe.is_file() and os.access(exe, os.X_OK)):
        pytest.skip(f"{name} is not built")
    return exe
