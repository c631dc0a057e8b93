"""Tests of hapticloth-fit: spline recovery, the monotone constraint, the four measured fabrics,
the fitted material library, and the error reports for bad input."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from buildpaths import program

from hapticloth import fit
from hapticloth.fit import Spline, fit_curve

REPO = Path(__file__).resolve().parents[2]
MEASURED = REPO / "tools" / "materials" / "measured"
LIBRARY = REPO / "tools" / "materials"
SCENE = REPO / "tools" / "scenes" / "hanging_square.toml"
FABRICS = sorted(p.stem for p in MEASURED.glob("*.csv"))
CURVES = ("weft", "warp", "shear")

# gray-interlock's shear curve is linear to within its measurement noise: the best linear law
# misses it by under 1% of the maximum stress, and the noise alone (estimated from the two
# branches of the odd curve) leaves about 0.25%. No law can be 5x better than the linear one
# there; for this curve the test asks instead that the fit sits at the noise floor.
NEAR_LINEAR = {("gray-interlock", "shear")}


def cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hapticloth.fit", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


def run_server(material: Path, tmp: Path) -> subprocess.CompletedProcess:
    """Step the hanging square scene with `material` for 0.05 s; skips without a build."""
    exe = program("hapticloth-server")
    text, n = re.subn(r"(?m)^material\s*=.*$",
                      lambda _: "material = " + json.dumps(str(material.resolve())),
                      SCENE.read_text())
    assert n == 1
    scene = tmp / f"scene-{material.stem}.toml"
    scene.write_text(text)
    return subprocess.run([str(exe), "--scene", str(scene), "--duration", "0.05", "--headless",
                           "--json"], capture_output=True, text=True, timeout=120)


def assert_server_accepts(material: Path, tmp: Path) -> None:
    r = run_server(material, tmp)
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    assert summary["finite"] is True
    assert summary["steps"] == 50


def write_csv(path: Path, curves: dict[str, tuple[np.ndarray, np.ndarray]],
              density: float = 0.2) -> Path:
    lines = ["# fabric: synthetic", f"# areal_density_kg_per_m2: {density}",
             "test,strain,stress"]
    for name, (e, s) in curves.items():
        lines += [f"{name},{a:.9g},{b:.9g}" for a, b in zip(e, s)]
    path.write_text("\n".join(lines) + "\n")
    return path


# --------------------------------------------------------------------------------------------
# Recovery of known splines
# --------------------------------------------------------------------------------------------

# Non-decreasing laws (checked below): a tensile one with three segments, an odd one with two.
TENSILE3 = (np.array([0.0, 0.1, 0.2]),
            np.array([[0, 100, 500, 1000], [0, 0, 6000, -4000], [0, 0, -5000, 2000]], float))
ODD2 = (np.array([0.0, 0.09]), np.array([[0, 40, 100, 1500], [0, 0, 2000, -6000]], float))


def synthetic(case: str, noise: float):
    if case == "tensile3":
        knots, B = TENSILE3
        spline = Spline(knots, B, odd=False)
        e = np.linspace(0.0, 0.3, 301)
    else:
        knots, B = ODD2
        spline = Spline(knots, B, odd=True)
        e = np.linspace(-0.14, 0.14, 281)
    assert spline.min_tangent(float(np.max(np.abs(e))))[0] > 0.0
    s = spline.stress(e)
    if noise:
        s = s + noise * np.max(np.abs(s)) * np.random.default_rng(7).standard_normal(e.size)
    return spline, e, s


@pytest.mark.parametrize("case", ["tensile3", "odd2"])
def test_recovers_spline_noise_free(case):
    truth, e, s = synthetic(case, 0.0)
    f = fit_curve("shear" if case == "odd2" else "weft", e, s, max_segments=3)
    # the odd2 case is fitted with up to 3 segments: the third must not be taken
    assert f.spline.segments == truth.segments
    assert np.max(np.abs(f.spline.knots - truth.knots)) < 1e-3
    nz = truth.B != 0.0
    assert np.all(f.spline.B[~nz] == 0.0)
    rel = np.abs(f.spline.B[nz] - truth.B[nz]) / np.abs(truth.B[nz])
    assert np.max(rel) < 1e-3
    assert f.pct(f.rms) < 1e-6
    assert not f.constrained


@pytest.mark.parametrize("case,knot_tol", [("tensile3", 0.01), ("odd2", 0.002)])
def test_recovers_spline_with_noise(case, knot_tol):
    noise = 0.002
    truth, e, s = synthetic(case, noise)
    f = fit_curve("shear" if case == "odd2" else "weft", e, s, max_segments=3)
    assert f.spline.segments == truth.segments
    assert np.max(np.abs(f.spline.knots - truth.knots)) < knot_tol
    # residuals at the noise level, and the fitted law close to the true one everywhere
    assert 0.85 * 100 * noise < f.pct(f.rms) < 1.1 * 100 * noise
    dense = np.linspace(e[0], e[-1], 2001)
    dev = np.max(np.abs(f.spline.stress(dense) - truth.stress(dense))) / f.max_stress
    assert dev < noise  # within the noise level (0.2% of max stress)


def test_segments_limit():
    truth, e, s = synthetic("tensile3", 0.0)
    f1 = fit_curve("weft", e, s, max_segments=1)
    f2 = fit_curve("weft", e, s, max_segments=2)
    assert f1.spline.segments == 1 and f2.spline.segments == 2
    assert f1.rms > f2.rms > 1e3 * fit_curve("weft", e, s, max_segments=3).rms


# --------------------------------------------------------------------------------------------
# Monotone constraint
# --------------------------------------------------------------------------------------------


def softening_curve():
    # stiff, then nearly flat with a slight drop: an unconstrained spline would decrease
    e = np.linspace(0.0, 0.3, 61)
    s = 80.0 * np.tanh(e / 0.06) - 10.0 * np.maximum(e - 0.2, 0.0)
    return e, s


def test_min_tangent_is_exact():
    rng = np.random.default_rng(3)
    for _ in range(200):
        k = int(rng.integers(1, 4))
        knots = np.concatenate([[0.0], np.sort(rng.uniform(0.02, 0.28, k - 1))])
        B = np.zeros((k, 4))
        B[0, 1:] = rng.normal(size=3) * [1.0, 10.0, 100.0]
        for i in range(1, k):
            B[i, 2:] = rng.normal(size=2) * [10.0, 100.0]
        ms = float(rng.uniform(0.05, 0.3))
        sp = Spline(knots, B, odd=False)
        t, x = sp.min_tangent(ms)
        sampled = sp.tangent(np.linspace(0.0, ms, 20001))
        assert t <= np.min(sampled) + 1e-12
        assert t > np.min(sampled) - 1e-3 * (1.0 + abs(t))
        assert abs(sp.tangent(x) - t) < 1e-9 * (1.0 + abs(t))
        assert 0.0 <= x <= ms


def test_lsi_matches_slsqp():
    from scipy.optimize import minimize

    rng = np.random.default_rng(5)
    E = rng.normal(size=(40, 5))
    f = rng.normal(size=40)
    G = rng.normal(size=(30, 5))
    x0 = rng.normal(size=5)
    h = G @ x0 - 0.1 * rng.uniform(size=30)  # x0 is feasible
    x = fit.lsi(E, f, G, h)
    assert np.all(G @ x >= h - 1e-9)
    ref = minimize(lambda y: np.sum((E @ y - f) ** 2), x0,
                   jac=lambda y: 2.0 * E.T @ (E @ y - f), method="SLSQP",
                   constraints=[{"type": "ineq", "fun": lambda y: G @ y - h,
                                 "jac": lambda y: G}],
                   options={"ftol": 1e-12, "maxiter": 500})
    assert ref.success, ref.message
    assert np.sum((E @ x - f) ** 2) <= ref.fun * (1.0 + 1e-9)
    assert np.allclose(x, ref.x, atol=1e-4)
    # the unconstrained solution violates some constraints, so they are active
    free = np.linalg.lstsq(E, f, rcond=None)[0]
    assert np.any(G @ free < h)


def test_monotone_constraint(tmp_path):
    e, s = softening_curve()
    f = fit_curve("weft", e, s, max_segments=3)
    assert f.constrained
    assert f.spline.min_tangent(0.3)[0] > -1e-6 * 80 / 0.3
    assert f.spline.server_check(0.3) >= 0.0
    assert f.pct(f.rms) < 1.0

    # without the constraint the best spline for the same knots decreases somewhere
    x = e / 0.3
    inner = f.spline.knots[1:] / 0.3
    c = np.linalg.lstsq(fit._basis(x, inner), s / np.max(s), rcond=None)[0]
    B = fit._coefficients_to_B(c, f.spline.segments)
    assert fit._min_tangent(np.concatenate([[0.0], inner]), B, 1.0)[0] < 0.0

    # the CLI writes a law the server accepts, while the server rejects the decreasing one
    lin = np.linspace(0.0, 0.2, 41)
    odd = np.linspace(-0.1, 0.1, 41)
    csv = write_csv(tmp_path / "soft.csv",
                    {"weft": (e, s), "warp": (lin, 500 * lin + 800 * lin ** 2),
                     "shear": (odd, 40 * odd + 200 * odd ** 3)})
    out = tmp_path / "soft.toml"
    r = cli(csv, "-o", out, "--json")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert report["curves"]["weft"]["monotone_constraint_active"] is True
    assert report["curves"]["warp"]["monotone_constraint_active"] is False
    assert_server_accepts(out, tmp_path)

    bad = tmp_path / "soft-unconstrained.toml"
    law = tomllib.loads(out.read_text())
    weft_B = B.copy()
    for j in range(4):
        weft_B[:, j] *= np.max(s) / 0.3 ** j
    text = out.read_text()
    start = text.index("[weft]")
    end = text.index("[warp]")
    section = (f"[weft]\nknots = {json.dumps(law['weft']['knots'])}\n"
               f"B = {json.dumps(weft_B.tolist())}\nmax_strain = 0.3\n\n")
    bad.write_text(text[:start] + section + text[end:])
    r = run_server(bad, tmp_path)
    assert r.returncode == 2
    assert "tangent" in r.stderr


# --------------------------------------------------------------------------------------------
# The four measured fabrics
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def fabric_fits(tmp_path_factory):
    """hapticloth-fit --json on each measured fabric, run concurrently."""
    assert len(FABRICS) == 4
    out = tmp_path_factory.mktemp("fits")
    procs = {}
    for stem in FABRICS:
        toml = out / f"{stem}.toml"
        cmd = [sys.executable, "-m", "hapticloth.fit", str(MEASURED / f"{stem}.csv"), "-o",
               str(toml), "--json"]
        procs[stem] = (toml, subprocess.Popen(cmd, stdout=subprocess.PIPE,
                                              stderr=subprocess.PIPE, text=True))
    results = {}
    for stem, (toml, p) in procs.items():
        stdout, stderr = p.communicate(timeout=300)
        assert p.returncode == 0, stderr
        results[stem] = (json.loads(stdout), toml)
    return results


def odd_noise_pct(csv: Path) -> float:
    """Noise of the shear curve from its two branches: s(e) + s(-e) is pure noise for an odd
    law; as % of the curve's max |stress|."""
    c = fit.read_measured(str(csv)).curves["shear"]
    assert np.allclose(c.strain, -c.strain[::-1])
    pair = (c.stress + c.stress[::-1])[: c.strain.size // 2]
    return 100.0 * np.sqrt(np.mean(pair ** 2) / 2.0) / np.max(np.abs(c.stress))


@pytest.mark.parametrize("stem", FABRICS)
def test_fabric_fit_quality(stem, fabric_fits):
    report, _ = fabric_fits[stem]
    assert report["file"].endswith(f"{stem}.csv")
    for name in CURVES:
        c = report["curves"][name]
        assert 1 <= c["segments"] <= 3
        assert len(c["knots"]) == c["segments"] == len(c["B"])
        assert c["rms_pct"] <= 1.0, (name, c["rms_pct"])
        assert c["max_pct"] <= 1.5, (name, c["max_pct"])
        assert c["rms_pct"] <= c["linear_rms_pct"]
        if (stem, name) in NEAR_LINEAR:
            assert c["linear_rms_pct"] < 1.5
            assert c["rms_pct"] <= 1.25 * odd_noise_pct(MEASURED / f"{stem}.csv")
            assert c["linear_rms_pct"] >= 3.0 * c["rms_pct"]
        else:
            assert c["linear_rms_pct"] >= 5.0 * c["rms_pct"], (name, c)


def test_near_linear_exception_is_needed(fabric_fits):
    # the exception above must stay limited to curves that really are linear within the noise
    for stem, name in NEAR_LINEAR:
        c = fabric_fits[stem][0]["curves"][name]
        assert c["linear_rms_pct"] < 5.0 * c["rms_pct"]


@pytest.mark.parametrize("stem", FABRICS)
def test_fabric_toml(stem, fabric_fits, tmp_path):
    report, toml = fabric_fits[stem]
    law = tomllib.loads(toml.read_text())
    assert set(law) == {"name", "areal_density", "source", "weft", "warp", "shear"}
    assert law["name"].startswith(stem)
    assert law["areal_density"] == report["areal_density"] > 0
    assert f"{stem}.csv" in law["source"]
    for name in CURVES:
        t = law[name]
        c = report["curves"][name]
        assert set(t) == {"knots", "B", "max_strain"}
        assert t["knots"] == c["knots"] and t["knots"][0] == 0.0
        assert t["B"] == c["B"]
        assert all(len(row) == 4 for row in t["B"])
        assert all(row[0] == 0.0 and row[1] == 0.0 for row in t["B"][1:])
        assert t["B"][0][0] == 0.0 and t["B"][0][1] >= 0.0
        assert t["max_strain"] == pytest.approx(c["max_strain"])
        spline = Spline(np.array(t["knots"]), np.array(t["B"]), odd=name == "shear")
        assert spline.min_tangent(t["max_strain"])[0] >= -1e-6 * c["max_stress"]
        assert spline.server_check(t["max_strain"]) >= 0.0
    assert_server_accepts(toml, tmp_path)


def test_text_output_and_plot(tmp_path):
    stem = "11oz-black-denim"
    png = tmp_path / "denim.png"
    out = tmp_path / "denim.toml"
    r = cli(MEASURED / f"{stem}.csv", "-o", out, "--plot", png)
    assert r.returncode == 0, r.stderr
    for name in CURVES:
        line = next(x for x in r.stdout.splitlines() if x.startswith(name + " "))
        assert len(re.findall(r"\d+\.\d\d%", line)) == 4, line
    assert f"wrote {out}" in r.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.stat().st_size > 20000
    assert tomllib.loads(out.read_text())["areal_density"] == 0.324


def test_segments_option(tmp_path, capsys):
    out = tmp_path / "w.toml"
    assert fit.main([str(MEASURED / "white-dots-on-blk.csv"), "-o", str(out), "--segments",
                     "1", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert all(c["segments"] == 1 for c in report["curves"].values())
    law = tomllib.loads(out.read_text())
    assert all(law[n]["knots"] == [0.0] for n in CURVES)
    r = cli(MEASURED / "white-dots-on-blk.csv", "-o", out, "--segments", "4")
    assert r.returncode == 2 and "--segments" in r.stderr


def test_refit_keeps_the_surface_section(tmp_path, capsys):
    """The [surface] tables (tactile rendering) are not fitted: a refit over a material file
    keeps them, with their comments, and the server still reads the file."""
    out = tmp_path / "w.toml"
    shipped = (LIBRARY / "white-dots-on-blk.toml").read_text()
    out.write_text(shipped)
    assert fit.main([str(MEASURED / "white-dots-on-blk.csv"), "-o", str(out)]) == 0
    capsys.readouterr()
    text = out.read_text()
    surface = shipped[shipped.index("# Surface for tactile rendering"):]
    assert text.endswith(surface), text[-600:]
    assert tomllib.loads(text)["surface"]["warp"]["yarn_spacing"] > 0.0
    assert_server_accepts(out, tmp_path)


# --------------------------------------------------------------------------------------------
# The committed material library
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("stem", FABRICS)
def test_library_material(stem, fabric_fits, tmp_path):
    path = LIBRARY / f"{stem}.toml"
    text = path.read_text()
    header = "\n".join(x for x in text.splitlines() if x.startswith("#"))
    assert "Fitted by hapticloth-fit" in header
    assert f"tools/materials/measured/{stem}.csv" in header
    assert "Wang, O'Brien and Ramamoorthi" in header
    assert (f"Regenerate: hapticloth-fit tools/materials/measured/{stem}.csv -o "
            f"tools/materials/{stem}.toml") in header
    law = tomllib.loads(text)
    report = fabric_fits[stem][0]
    # up to date: the committed laws agree with a fresh fit at the measured strains
    measured = fit.read_measured(str(MEASURED / f"{stem}.csv"))
    for name in CURVES:
        c = measured.curves[name]
        odd = name == "shear"
        committed = Spline(np.array(law[name]["knots"]), np.array(law[name]["B"]), odd)
        fresh = report["curves"][name]
        fresh_spline = Spline(np.array(fresh["knots"]), np.array(fresh["B"]), odd)
        diff = np.max(np.abs(committed.stress(c.strain) - fresh_spline.stress(c.strain)))
        assert diff <= 1e-6 * fresh["max_stress"], (name, diff)
    assert_server_accepts(path, tmp_path)


# --------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------


def good_lines() -> list[str]:
    lines = ["# fabric: tiny", "# areal_density_kg_per_m2: 0.2", "test,strain,stress"]
    for name in ("weft", "warp"):
        lines += [f"{name},{0.01 * i:.2f},{10.0 * i + i * i:.1f}" for i in range(8)]
    lines += [f"shear,{0.02 * i:.2f},{0.5 * i:.2f}" for i in range(-5, 6)]
    return lines


def replace(lines, old, new):
    i = lines.index(old)
    return lines[:i] + ([new] if new is not None else []) + lines[i + 1:]


# line numbers: 1-2 comments, 3 header row, 4-11 weft, 12-19 warp, 20-30 shear
BAD_CASES = {
    "missing_header_row": (lambda L: replace(L, "test,strain,stress", None), 3, "header row"),
    "missing_column": (lambda L: replace(L, "test,strain,stress", "test,strain,force"), 3,
                       "stress"),
    "wrong_field_count": (lambda L: replace(L, "weft,0.03,39.0", "weft,0.03"), 7,
                          "comma-separated"),
    "not_a_number": (lambda L: replace(L, "warp,0.02,24.0", "warp,0.02,24.0x"), 14,
                     "not a number"),
    "strain_not_a_number": (lambda L: replace(L, "warp,0.02,24.0", "warp,abc,24.0"), 14,
                            "not a number"),
    "not_finite": (lambda L: replace(L, "warp,0.02,24.0", "warp,0.02,nan"), 14, "finite"),
    "strain_not_increasing": (lambda L: replace(L, "weft,0.05,75.0", "weft,0.04,75.0"), 9,
                              "strictly increasing"),
    "too_few_points": (lambda L: [x for x in L if not x.startswith("warp,")
                                  or x in ("warp,0.00,0.0", "warp,0.01,11.0", "warp,0.02,24.0")],
                       12, "too few points"),
    "unknown_test": (lambda L: replace(L, "shear,0.04,1.00", "bias,0.04,1.00"), 27,
                     "unknown test"),
    "missing_test": (lambda L: [x for x in L if not x.startswith("shear,")], 3,
                     "missing test 'shear'"),
    "missing_areal_density": (lambda L: replace(L, "# areal_density_kg_per_m2: 0.2", None), 1,
                              "areal_density_kg_per_m2"),
    "bad_areal_density": (lambda L: replace(L, "# areal_density_kg_per_m2: 0.2",
                                            "# areal_density_kg_per_m2: -0.2"), 2, "> 0"),
    "negative_tensile_strain": (lambda L: replace(L, "weft,0.00,0.0", "weft,-0.01,0.0"), 4,
                                "negative strain"),
}


def test_good_lines_fit(tmp_path):
    # the base of the bad cases is itself accepted
    csv = tmp_path / "good.csv"
    csv.write_text("\n".join(good_lines()) + "\n")
    r = cli(csv, "-o", tmp_path / "good.toml", "--segments", "1")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "good.toml").exists()


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_csv(case, tmp_path):
    edit, line, keyword = BAD_CASES[case]
    lines = edit(good_lines())
    assert lines != good_lines()
    csv = tmp_path / f"{case}.csv"
    csv.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out.toml"
    r = cli(csv, "-o", out)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert f"{csv}:{line}:" in r.stderr, r.stderr
    assert keyword in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1  # one line, no traceback
    assert not out.exists()


def test_missing_input_file(tmp_path):
    missing = tmp_path / "nope.csv"
    r = cli(missing, "-o", tmp_path / "out.toml")
    assert r.returncode == 2
    assert str(missing) in r.stderr and "no such file" in r.stderr.lower()
    assert "Traceback" not in r.stderr


def test_empty_file(tmp_path):
    csv = tmp_path / "empty.csv"
    csv.write_text("")
    r = cli(csv, "-o", tmp_path / "out.toml")
    assert r.returncode == 2
    assert f"{csv}:1:" in r.stderr and "header row" in r.stderr


# --------------------------------------------------------------------------------------------
# User errors through the console script: one line naming the file, line or option, exit 2
# --------------------------------------------------------------------------------------------


def fit_tool(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """hapticloth-fit as installed (the venv's console script: the real entry point)."""
    exe = Path(sys.executable).parent / "hapticloth-fit"
    if not exe.is_file():
        pytest.skip("hapticloth-fit is not installed in the venv (tools/setup)")
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


def assert_user_error(r: subprocess.CompletedProcess, *named: str) -> None:
    assert "Traceback" not in r.stdout + r.stderr, r.stderr
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert r.stderr.count("\n") == 1, r.stderr  # one line
    for n in named:
        assert n in r.stderr, (n, r.stderr)


@pytest.mark.parametrize("value", ["1e300", "-1e300", "2e6"])
def test_huge_stress_is_a_line_error(value, tmp_path):
    # A fabric CSV with one stress far out of range (1e300 once overflowed inside the fit).
    lines = (MEASURED / "11oz-black-denim.csv").read_text().splitlines()
    i = next(k for k, x in enumerate(lines) if x.startswith("warp,"))
    test, strain, _ = lines[i + 3].split(",")
    lines[i + 3] = f"{test},{strain},{value}"
    csv = tmp_path / "huge.csv"
    csv.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out.toml"
    r = fit_tool(csv, "-o", out)
    assert_user_error(r, f"{csv}:{i + 4}: stress {value} is outside")
    assert not out.exists()


def test_strain_in_percent_is_a_line_error(tmp_path):
    lines = replace(good_lines(), "weft,0.07,119.0", "weft,70,119.0")
    csv = tmp_path / "percent.csv"
    csv.write_text("\n".join(lines) + "\n")
    assert_user_error(fit_tool(csv, "-o", tmp_path / "out.toml"), f"{csv}:11: strain 70",
                      "not percent")


@pytest.mark.parametrize("option", ["-o", "--plot"])
def test_unwritable_output_is_named_before_the_fit(option, tmp_path):
    csv = tmp_path / "good.csv"
    csv.write_text("\n".join(good_lines()) + "\n")
    bad = tmp_path / "missing" / "out.file"
    out = tmp_path / "out.toml"
    args = ["-o", bad] if option == "-o" else ["-o", out, "--plot", bad]
    r = fit_tool(csv, *args, "--segments", "1")
    long_option = {"-o": "--output", "--plot": "--plot"}[option]
    assert_user_error(r, f"{long_option} {bad}: cannot write: the folder {bad.parent} does not exist")
    assert not out.exists()  # neither output is written when one cannot be


def test_output_is_a_folder(tmp_path):
    csv = tmp_path / "good.csv"
    csv.write_text("\n".join(good_lines()) + "\n")
    assert_user_error(fit_tool(csv, "-o", tmp_path), f"--output {tmp_path}: is a folder")


def test_output_that_would_destroy_the_input_or_names_nothing(tmp_path):
    """Issue 36 item 9: `-o in.csv` overwrote the measured data with the TOML; `-o ""` was
    ignored."""
    csv = tmp_path / "good.csv"
    csv.write_text("\n".join(good_lines()) + "\n")
    before = csv.read_text()
    assert_user_error(fit_tool(csv, "-o", csv), f"--output {csv}: is the input {csv}")
    assert csv.read_text() == before
    assert_user_error(fit_tool(csv, "-o", ""), "--output: needs a path")
    out = tmp_path / "out.toml"
    assert_user_error(fit_tool(csv, "-o", out, "--plot", tmp_path / "plot.txt"), "must end in .png")
    assert not out.exists()
