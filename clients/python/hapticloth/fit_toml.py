"""The material TOML file of fitted spline laws, as read by hapticloth-server."""

from __future__ import annotations

from .fit_csv import CURVES, Measured
from .fit_curves import CurveFit


def _toml_string(s: str) -> str:
    out = s.replace("\\", "\\\\").replace('"', '\\"')
    out = "".join(ch if ch >= " " or ch == "\t" else f"\\u{ord(ch):04x}" for ch in out)
    return f'"{out}"'


def _num(x: float) -> str:
    x = float(x)
    if x == 0.0:
        return "0.0"
    return repr(x)


def material_toml(measured: Measured, fits: dict[str, CurveFit], command: str) -> str:
    name = measured.name
    rms_text = ", ".join(f"{n} {fits[n].pct(fits[n].rms):.2f}%" for n in CURVES)
    lines = [f"# Fitted by hapticloth-fit from {measured.path}"]
    if measured.source:
        lines.append(f"# Data: {measured.source}")
    lines += [
        "# Spline law of HAPTEX appendix A.2; knots by nonlinear least squares, coefficients by",
        "# linear least squares for those knots, tangent kept >= 0 up to max_strain.",
        f"# Regenerate: {command}",
    ]
    for n in CURVES:
        f = fits[n]
        lines.append(
            f"#   {n + ':':<6} {f.spline.segments} segment{'s' if f.spline.segments > 1 else ' '}, "
            f"RMS {f.pct(f.rms):.2f}% and max {f.pct(f.max):.2f}% of max |stress| "
            f"{f.max_stress:.4g} N/m; linear law RMS {f.pct(f.linear_rms):.2f}%")
    wrapped = []
    for line in lines:
        wrapped += _wrap_comment(line)
    out = wrapped + [
        f"name = {_toml_string(name)}",
        f"areal_density = {_num(measured.areal_density)}  # kg/m^2",
        f"source = {_toml_string(f'hapticloth-fit {measured.path} (RMS of max stress: {rms_text})')}",
    ]
    for n in CURVES:
        f = fits[n]
        s = f.spline
        what = {"weft": "sigma_uu(eps_uu)", "warp": "sigma_vv(eps_vv)",
                "shear": "sigma_uv(eps_uv), odd"}[n]
        out += [
            "",
            f"[{n}]  # {what}, N/m",
            "knots = [" + ", ".join(_num(k) for k in s.knots) + "]",
            "B = [" + ",\n     ".join(
                "[" + ", ".join(_num(b) for b in row) + "]" for row in s.B) + "]",
            f"max_strain = {_num(f.max_strain)}",
        ]
    return "\n".join(out) + "\n"


def _wrap_comment(line: str, width: int = 100) -> list[str]:
    if len(line) <= width or line.startswith("# Regenerate:"):
        return [line]
    indent = "#   " if not line.startswith("#   ") else "#     "
    out, current = [], ""
    for word in line.split(" "):
        if current and len(current) + 1 + len(word) > width:
            out.append(current)
            current = indent + word
        else:
            current = f"{current} {word}" if current else word
    out.append(current)
    return out


def kept_surface(path: str) -> str:
    """The [surface] tables (tactile rendering, not fitted here) of an existing material file,
    with the comment lines just above them, so that a refit keeps them; "" if there are none."""
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except OSError:
        return ""
    start = next((i for i, x in enumerate(lines) if x.startswith("[surface")), None)
    if start is None:
        return ""
    while start > 0 and lines[start - 1].startswith("#"):
        start -= 1
    return "\n" + "\n".join(lines[start:]) + "\n"
