"""Endless and huge inputs (devices/log/input_file.cpp, hapticloth.errors.check_input_file;
issue 36 item 6): /dev/zero given as each kind of input file the programs read, and a 2 GiB
sparse scene, are refused at once by name: exit 2 (1 for hapticloth-export, whose errors all
exit 1), the path and "not a regular file" or its size in the message, no traceback, within
10 s each and without the memory they used to grow into (0.7 GB/s until killed).
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from buildpaths import REPO, program

SCENE = REPO / "tools" / "scenes" / "hanging_square.toml"
VENV_BIN = Path(sys.executable).parent


def refused(cmd, path, code=2, why="not a regular file"):
    t0 = time.monotonic()
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=10)
    took = time.monotonic() - t0
    assert r.returncode == code, (cmd, r.returncode, r.stderr[-2000:])
    assert f"{path}" in r.stderr and why in r.stderr, (cmd, r.stderr)
    assert "Traceback" not in r.stderr
    return took


def zero_link(tmp_path, name):
    """A name with the extension a reader wants, for /dev/zero."""
    link = tmp_path / name
    link.symlink_to("/dev/zero")
    return link


def scene_with(tmp_path, key, value):
    text = SCENE.read_text().replace('material = "../materials/denim-handmade.toml"',
                                     f'material = "{REPO}/tools/materials/denim-handmade.toml"')
    if key == "material":
        text = text.replace(f'material = "{REPO}/tools/materials/denim-handmade.toml"', f'material = "{value}"')
    elif key == "script":
        text = text.replace('script = "touch_stroke_pinch.toml"', f'script = "{value}"')
    p = tmp_path / f"{key}.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("what", ["scene", "material", "script", "replay", "zenoh-config",
                                  "export", "render"])
def test_dev_zero_is_refused_by_name(what, tmp_path):
    server = program("hapticloth-server")
    run = ["--duration", "1", "--no-lcm-log"]
    cmd = {
        "scene": [server, "--scene", "/dev/zero", "--headless"],
        "material": [server, "--scene", scene_with(tmp_path, "material", "/dev/zero"), "--headless"],
        "script": [server, "--scene", scene_with(tmp_path, "script", zero_link(tmp_path, "zero.toml")),
                   "--no-zenoh", *run],
        "replay": [server, "--scene", SCENE, "--device", "replay", "--replay", "/dev/zero", "--no-zenoh", *run],
        "zenoh-config": [server, "--scene", SCENE, "--zenoh-config", "/dev/zero", *run],
        "export": [program("hapticloth-export"), "/dev/zero", "-o", tmp_path / "x.mcap"],
        "render": [program("hapticloth-render"), "--log", "/dev/zero", "--snapshot", tmp_path / "x.png"],
    }[what]
    refused(cmd, tmp_path / "zero.toml" if what == "script" else "/dev/zero",
            code=1 if what == "export" else 2)


@pytest.mark.parametrize("tool", ["hapticloth-fit", "hapticloth-plot", "hapticloth-replay"])
def test_python_tools_refuse_dev_zero(tool, tmp_path):
    exe = VENV_BIN / tool
    if not exe.is_file():
        pytest.skip(f"{tool} is not installed")
    args = {"hapticloth-fit": ["/dev/zero", "-o", tmp_path / "m.toml"],
            "hapticloth-plot": ["/dev/zero", "-o", tmp_path / "p.png"],
            "hapticloth-replay": ["/dev/zero", "--timeout", "1"]}[tool]
    refused([exe, *args], "/dev/zero")


def test_a_huge_sparse_scene_is_refused_by_its_size(tmp_path):
    big = tmp_path / "big.toml"
    with big.open("wb") as f:
        f.truncate(2 << 30)  # sparse: nothing written
    took = refused([program("hapticloth-server"), "--scene", big, "--headless"], big,
                   why="more than the 64 MiB")
    assert took < 5.0, f"refused after {took:.1f} s"  # a safety limit: refused by its size, not read
