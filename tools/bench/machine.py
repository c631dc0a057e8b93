"""What the benchmark scripts say about the machine they ran on."""
import pathlib


def cpu_model():
    """The CPU's model name from /proc/cpuinfo ("unknown" where it has none)."""
    for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return "unknown"
