"""User errors of the command-line tools.

Every tool runs its main function through `run_cli`: a mistake of the user's (a bad option
value, an unreadable or unwritable file, a server that is not there) is one line on stderr,
``prog: message``, naming the option, file (and line) or endpoint at fault, and exit status 2.
A traceback is left for bugs.

Exit status of every tool: 0 done; 1 done, but the server said no (hapticloth-replay and
hapticloth-inject: a command rejected or unanswered) or the work failed; 2 a user error
(argparse's usage errors included).
"""

from __future__ import annotations

import math
import os
import re
import stat
import sys

EXIT_FAILED = 1
EXIT_USER_ERROR = 2


class UserError(Exception):
    """A mistake in the command line, an input file or the server's address. The message
    names what is at fault (``--duration: ...``, ``FILE:LINE: ...``, ``--endpoint ...``)."""


def run_cli(prog, main, argv=None) -> int:
    """main(argv)'s exit status; UserError, OSError and the transports' connection errors
    become ``prog: message`` on stderr and exit status 2."""
    try:
        return main(argv)
    except UserError as e:
        _say(prog, str(e))
    except OSError as e:
        _say(prog, os_error_text(e))
    except KeyboardInterrupt:
        _say(prog, "interrupted")
        return 130
    except Exception as e:
        if not isinstance(e, transport_errors()):
            raise
        _say(prog, transport_error_text(e))
    return EXIT_USER_ERROR


def _say(prog, message):
    print(f"{prog}: {message}", file=sys.stderr, flush=True)


def os_error_text(e: OSError) -> str:
    """FILE: reason (what open() and friends say, without the errno)."""
    reason = e.strerror or str(e)
    return f"{e.filename}: {reason}" if e.filename else reason


def transport_errors() -> tuple:
    """The exception classes of the transports already loaded (zenoh's ZError): an error of
    the connection, not of this program. Not imported here, so a tool without a transport
    does not pay for loading it."""
    z = sys.modules.get("zenoh")
    return (z.ZError,) if z is not None and hasattr(z, "ZError") else ()


def transport_error_text(e: Exception) -> str:
    """zenoh's message without the Rust source location it appends (`... at /path/x.rs:447.`)."""
    text = re.sub(r"\s+at \S+\.rs:\d+\.?\s*$", "", str(e).strip())
    return text.rstrip("!. ") or type(e).__name__


def check_number(option, value, what, low=-math.inf, high=math.inf, low_open=False, unit=""):
    """`value` if it is finite and in [low, high] ((low, high] with low_open); else UserError
    ``OPTION: must be WHAT, not VALUE`` (too small or not a number) or ``OPTION: must be at most
    HIGH UNIT, not VALUE`` (too large)."""
    above_low = value > low if low_open else value >= low
    if math.isnan(value) or not above_low:
        raise UserError(f"{option}: must be {what}, not {value:g}")
    if math.isinf(value) or value > high:
        raise UserError(f"{option}: must be at most {high:g}{unit}, not {value:g}")
    return value


def check_writable(path, option=None, inputs=(), suffixes=()) -> None:
    """UserError naming `path` (and the option that gave it) unless a file can be written
    there: checked before the work, so that a run or a fit is not lost to a typo in its
    output path. Also refused: an empty path, what is not a regular file (/dev/full, a FIFO),
    one of the run's `inputs` (it would be overwritten with the output), and a name not ending
    in one of `suffixes` when they are given (the format is chosen by it)."""
    p = os.fspath(path)
    where = f"{option} {p}" if option else p
    if not p:
        raise UserError(f"{option or 'output'}: needs a path (an empty one names no file)")
    if os.path.exists(p) and not os.path.isdir(p) and not stat.S_ISREG(os.stat(p).st_mode):
        raise UserError(f"{where}: not a regular file (a device or FIFO); give a file to write")
    for i in inputs:
        if os.path.exists(p) and os.path.exists(i) and os.path.samefile(p, i):
            raise UserError(f"{where}: is the input {os.fspath(i)}; writing it would destroy it")
    if os.path.isdir(p):
        raise UserError(f"{where}: is a folder, not a file to write")
    folder = os.path.dirname(p) or "."
    if not os.path.exists(folder):
        raise UserError(f"{where}: cannot write: the folder {folder} does not exist")
    if not os.path.isdir(folder):
        raise UserError(f"{where}: cannot write: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK) or (os.path.exists(p) and not os.access(p, os.W_OK)):
        raise UserError(f"{where}: cannot write: permission denied")
    if suffixes and not p.lower().endswith(tuple(suffixes)):
        raise UserError(f"{where}: must end in {' or '.join(suffixes)} (the format written)")


#: bytes: the largest input a tool reads (a device log of an hour at 1 kHz is about 0.7 GB)
MAX_INPUT_BYTES = 2 << 30


def check_input_file(path, option=None, max_bytes=MAX_INPUT_BYTES) -> None:
    """UserError naming `path` unless it is an existing regular file of at most `max_bytes`
    (a device such as /dev/zero, a FIFO or a huge file would hang the reader or fill memory)."""
    p = os.fspath(path)
    where = f"{option} {p}" if option else p
    if not os.path.exists(p):
        raise UserError(f"{where}: no such file")
    if os.path.isdir(p):
        raise UserError(f"{where}: is a folder, not a file")
    st = os.stat(p)
    if not stat.S_ISREG(st.st_mode):
        raise UserError(f"{where}: not a regular file (a device, FIFO or socket is not read as input)")
    if st.st_size > max_bytes:
        raise UserError(f"{where}: {st.st_size} bytes, more than the {max_bytes >> 20} MiB an "
                        "input may have")


def not_text_error(path, e: UnicodeDecodeError) -> UserError:
    """The error for a binary file where a text file was expected: names the file and the
    first byte that is not UTF-8."""
    bad = e.object[e.start:e.start + 1]
    return UserError(f"{path}: not a text file (byte 0x{bad.hex()} at offset {e.start} is not UTF-8)")


__all__ = ["UserError", "run_cli", "check_number", "check_writable", "check_input_file",
           "not_text_error", "os_error_text", "transport_errors", "transport_error_text",
           "EXIT_FAILED", "EXIT_USER_ERROR"]
