"""Bad command-line options of the C++ programs (issue 14): a numeric option that is not a
finite number in its range, an output into a missing folder, or an option the program does not
know is a usage error: exit 2 with the option (and the bad value) named on stderr, before any
work (nothing on stdout, no output file written, no session, test or benchmark run). Every
valid run of these command lines is short, so an option that slipped through is seen as a
finished run rather than a hang.

Also: `hapticloth-bench --help` lists the `udp` and `transport` subcommands.
"""

from __future__ import annotations

import re
import shutil
import socket
import subprocess
from pathlib import Path

import pytest

from server_session import SCENE, Server, wait_for_program

REPO = Path(__file__).resolve().parents[2]
MATERIAL = REPO / "tools" / "materials" / "denim-handmade.toml"
UNKNOWN = "--no-such-option"


@pytest.fixture(scope="module")
def lcm_log(tmp_path_factory):
    """A short server run's LCM log, for hapticloth-render to have something real to draw."""
    d = tmp_path_factory.mktemp("render_log")
    log = d / "session.lcm"
    with Server("--device", "mock", "--fast", "--duration", "0.2", "--no-zenoh", cwd=d,
                lcm_log=log) as srv:
        assert srv.finish(seconds=120) == 0, srv.stderr
    return log


def base_args(program: str, option: str, tmp: Path, log: Path | None) -> list[str]:
    """A valid, short command line of `program` (with `option` left for the case to give), and
    the outputs it would write."""
    if program == "hapticloth-server":
        args = ["--scene", SCENE, "--device", "mock", "--fast"]
        args += [] if option == "--zenoh-listen" else ["--no-zenoh"]
        args += [] if option == "--lcm-log" else ["--no-lcm-log"]
        args += [] if option == "--record" else ["--record", tmp / "record.csv"]
        return args if option == "--duration" else args + ["--duration", "0.5"]
    if program == "hapticloth-bench step":
        return ["--scene", SCENE, "--steps", "3", "--json"]
    if program == "hapticloth-bench haptic":
        return ["--json"] + ([] if option == "--duration" else ["--duration", "0.5"])
    if program in ("hapticloth-bench", "hapticloth-bench udp"):
        return []
    if program in ("hapticloth-bench accuracy", "hapticloth-bench stability"):
        return ["--quick", "--json"]
    if program == "hapticloth-bench timer":
        return ["--json"] + ([] if option == "--ticks" else ["--ticks", "10"])
    if program == "hapticloth-kes":
        return [MATERIAL, "--test", "weft", "--steps", "3", "--csv", tmp / "curve.csv"]
    if program == "hapticloth-render":
        return ["--log", log, "--snapshot", tmp / "snapshot.png"]
    if program == "hapticloth-bench-udp":
        return ["--json"] + ([] if option == "--duration" else ["--duration", "0.2"])
    raise ValueError(program)


def case(program, option, value=None, **kw):
    words = [program.removeprefix("hapticloth-"), option.removeprefix("--")]
    words += [] if value is None else [value.replace("{tmp}/", "")]
    return pytest.param(program, option, value, id=" ".join(words), **kw)


BAD = [
    # hapticloth-server
    case("hapticloth-server", "--dt", "-1"),
    case("hapticloth-server", "--dt", "0"),
    case("hapticloth-server", "--dt", "nan"),
    case("hapticloth-server", "--dt", "1e9"),
    case("hapticloth-server", "--alpha", "nan"),
    case("hapticloth-server", "--alpha", "0.2"),
    case("hapticloth-server", "--duration", "-1"),
    case("hapticloth-server", "--duration", "0"),
    case("hapticloth-server", "--duration", "nan"),
    case("hapticloth-server", "--duration", "inf"),
    case("hapticloth-server", "--max-command-speed", "-1"),
    case("hapticloth-server", "--max-command-speed", "0"),
    case("hapticloth-server", "--max-command-speed", "nan"),
    case("hapticloth-server", "--cloth-rate", "0"),
    case("hapticloth-server", "--record", "{tmp}/missing/record.csv"),
    case("hapticloth-server", "--clock", "gps"),
    case("hapticloth-server", UNKNOWN),
    # Issue 36 items 8, 9 and 11: network options, output paths and values that ran (or failed
    # only after the preroll) before.
    case("hapticloth-server", "--dt", "1e-300"),
    case("hapticloth-server", "--solver", ""),
    case("hapticloth-server", "--device", ""),
    case("hapticloth-server", "--record", ""),
    case("hapticloth-server", "--lcm-log", ""),
    case("hapticloth-server", "--lcm-log", "/dev/full"),
    case("hapticloth-server", "--zenoh-listen", "garbage"),
    case("hapticloth-server", "--lcm-url", "nosuch://x"),
    case("hapticloth-server", "--foxglove", "nohost.invalid:1"),
    case("hapticloth-server", "--name", "a/b"),
    # hapticloth-bench
    case("hapticloth-bench step", "--dt", "-1"),
    case("hapticloth-bench step", "--pcg-tolerance", "-1"),
    case("hapticloth-bench step", "--pcg-tolerance", "0"),
    case("hapticloth-bench step", UNKNOWN),
    case("hapticloth-bench haptic", "--duration", "-1"),
    case("hapticloth-bench haptic", "--duration", "0"),
    case("hapticloth-bench haptic", UNKNOWN),
    case("hapticloth-bench udp", "--duration", "nan"),
    case("hapticloth-bench timer", "--ticks", "0"),
    case("hapticloth-bench timer", "--priority", "100"),
    case("hapticloth-bench accuracy", "--refine", "sometimes"),
    case("hapticloth-bench stability", "--refine", "sometimes"),
    case("hapticloth-bench", UNKNOWN),
    # hapticloth-kes
    case("hapticloth-kes", "--max-strain", "-1"),
    case("hapticloth-kes", "--max-strain", "nan"),
    case("hapticloth-kes", "--plot", "{tmp}/missing/plot.png"),
    case("hapticloth-kes", UNKNOWN),
    # hapticloth-render
    case("hapticloth-render", "--fov", "nan"),
    case("hapticloth-render", "--fps", "0"),
    case("hapticloth-render", UNKNOWN),
    # hapticloth-bench-udp
    case("hapticloth-bench-udp", "--duration", "nan"),
    case("hapticloth-bench-udp", "--clock", "gps"),
    case("hapticloth-bench-udp", UNKNOWN),
]


@pytest.mark.parametrize("program,option,value", BAD)
def test_bad_option_exits_2_naming_it_before_any_work(program, option, value, tmp_path, request):
    exe, *sub = program.split()
    log = request.getfixturevalue("lcm_log") if exe == "hapticloth-render" else None
    value = None if value is None else value.replace("{tmp}", str(tmp_path))
    out = tmp_path / "out"
    out.mkdir()
    args = [*sub, *base_args(program, option, out, log), option]
    args += [] if value is None else [value]
    r = subprocess.run([str(wait_for_program(exe)), *map(str, args)], cwd=out, capture_output=True,
                       text=True, timeout=120)
    said = f"exit {r.returncode}\nstdout: {r.stdout[-1000:]}\nstderr: {r.stderr[-1000:]}"
    assert r.returncode == 2, said
    assert option in r.stderr, said
    if value is not None:
        assert value in r.stderr, said
    # Nothing ran: no output, nothing written (the server's record, kes's curve, the snapshot,
    # a default LCM log under out/).
    assert r.stdout == "", said
    assert sorted(p.name for p in out.iterdir()) == [], said


def test_bench_help_lists_udp_and_transport():
    r = subprocess.run([str(wait_for_program("hapticloth-bench")), "--help"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    subcommands = r.stdout.split("Subcommands:", 1)[1]
    listed = [line.split()[0] for line in subcommands.splitlines() if line.strip()]
    for name in ("udp", "transport"):
        assert name in listed, r.stdout


@pytest.mark.parametrize("program", ["hapticloth-server", "hapticloth-bench step",
                                     "hapticloth-bench haptic", "hapticloth-kes",
                                     "hapticloth-render", "hapticloth-bench-udp"])
def test_the_command_lines_run_without_the_bad_option(program, tmp_path, request):
    # The table's command lines are valid as they stand: the exit 2 above is the bad option's,
    # and a run that does start prints and writes what the table checks is absent.
    exe, *sub = program.split()
    log = request.getfixturevalue("lcm_log") if exe == "hapticloth-render" else None
    out = tmp_path / "out"
    out.mkdir()
    args = [*sub, *base_args(program, "", out, log)]
    r = subprocess.run([str(wait_for_program(exe)), *map(str, args)], cwd=out, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stdout[-1000:]}\n{r.stderr[-1000:]}"
    assert r.stdout.strip() or any(out.iterdir()), "a run that prints and writes nothing"
    written = {"hapticloth-server": "record.csv", "hapticloth-kes": "curve.csv",
               "hapticloth-render": "snapshot.png"}.get(exe)
    if written:
        assert (out / written).is_file() and (out / written).stat().st_size > 0


@pytest.fixture
def held_tcp_port():
    """A TCP port on 127.0.0.1 that this test listens on: zenoh cannot listen there."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield s.getsockname()[1]


# Issue 36 item 8: what only opening the transport finds (a port in use, a host that does not
# resolve, a zenoh config zenoh refuses) was exit 2 after the whole preroll. With a 600 s
# preroll (over a minute of steps even as fast as possible), an error that waited for it would
# not come within the 60 s this allows.
@pytest.mark.parametrize("kind", ["zenoh port in use", "foxglove host", "zenoh config"])
def test_transport_errors_come_before_the_preroll(kind, held_tcp_port, tmp_path):
    for folder in ("scenes", "materials"):  # the scene with its script and material beside it
        shutil.copytree(REPO / "tools" / folder, tmp_path / folder)
    scene = tmp_path / "scenes" / "long_preroll.toml"
    scene.write_text(re.sub(r"(?m)^preroll = [0-9.]+", "preroll = 600.0", SCENE.read_text()))
    option, value, words = {
        "zenoh port in use": ("--zenoh-listen", f"tcp/127.0.0.1:{held_tcp_port}", "in use"),
        "foxglove host": ("--foxglove", "nohost.invalid:1", "nohost.invalid"),
        "zenoh config": ("--zenoh-config", str(tmp_path / "bad.json5"), "bad.json5"),
    }[kind]
    (tmp_path / "bad.json5").write_text("{ mode: \"nonsense\" }\n")
    out = tmp_path / "out"
    out.mkdir()
    args = ["--scene", scene, "--device", "mock", "--fast", "--duration", "0.5",
            "--record", out / "record.csv", "--lcm-log", out / "session.lcm", option, value]
    try:
        r = subprocess.run([str(wait_for_program("hapticloth-server")), *map(str, args)], cwd=out,
                           capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{option} {value}: no error within 60 s of a 600 s preroll")
    said = f"exit {r.returncode}\nstdout: {r.stdout[-1000:]}\nstderr: {r.stderr[-1000:]}"
    assert r.returncode == 2, said
    assert words in r.stderr, said
    assert ".rs:" not in r.stderr and ".cargo" not in r.stderr, said  # zenoh's source paths
    assert "stage" not in r.stdout, said  # nothing planned, nothing settled
    assert sorted(p.name for p in out.iterdir()) == [], said  # the claimed record and log removed
