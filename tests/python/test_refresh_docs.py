"""The README's example of the main job's output is the server's output today: the block
between the main-job-output markers (written by tools/refresh-docs) has every summary line the
server prints now, and no line it no longer prints (a short real-time run, as the main job's)."""

import re
import subprocess

from buildpaths import REPO, program


def labels(text):
    """The label column of a summary (`label  value...`), in order."""
    out = []
    for line in text.splitlines():
        m = re.match(r"^([a-z][a-z0-9 -]*?[a-z0-9])\s{2,}\S", line) or re.match(r"^(fingertip contact) ", line)
        if m:
            out.append(m.group(1))
    return out


def readme_block():
    text = (REPO / "README.md").read_text()
    m = re.search(r"<!-- main-job-output:begin -->\n```\n(.*?)```\n<!-- main-job-output:end -->", text, re.S)
    assert m, "README.md: the main-job-output block (tools/refresh-docs) is missing"
    return m.group(1)


def test_readme_main_job_output_has_the_lines_the_server_prints():
    r = subprocess.run([str(program("hapticloth-server")), "--scene", str(REPO / "tools/scenes/hanging_square.toml"),
                        "--duration", "0.3", "--no-zenoh", "--no-lcm-log"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    now = sorted(set(labels(r.stdout)))
    assert "haptic ticks" in now and "safety gate" in now, r.stdout
    shown = sorted(set(labels(readme_block())))
    assert shown == now, "run tools/refresh-docs: the README shows %s, the server prints %s" % (shown, now)
