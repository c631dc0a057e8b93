"""Tests of hapticloth-kes, the simulated Kawabata tests, on the fitted material library:
the simulated tensile and shear tests reproduce each material law within 0.5% of max stress,
the measured points are compared, and bad input gets a clear error and exit code 2."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from buildpaths import program

REPO = Path(__file__).resolve().parents[2]
MEASURED = REPO / "tools" / "materials" / "measured"
LIBRARY = REPO / "tools" / "materials"
FABRICS = sorted(p.stem for p in MEASURED.glob("*.csv"))


def kes(*args, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([str(program("hapticloth-kes")), *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


@pytest.mark.parametrize("fabric", FABRICS)
@pytest.mark.parametrize("test", ["weft", "warp", "shear"])
def test_simulated_test_reproduces_the_law(fabric, test, tmp_path):
    out = tmp_path / "curve.csv"
    r = kes(LIBRARY / f"{fabric}.toml", "--test", test, "--measured", MEASURED / f"{fabric}.csv",
            "--json", "--csv", out)
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["test"] == test
    assert d["points"] >= 31
    assert d["material_max_pct"] <= 0.5
    assert d["material_rms_pct"] <= 0.5
    # The measured points: the fit's own error plus the data's 0.4% noise.
    assert d["measured_rms_pct"] <= 1.0
    # The test reaches the law's largest strain (tensile) or +-8 degrees (shear).
    rows = [line.split(",") for line in out.read_text().splitlines()[1:]]
    strains = [float(r[0]) for r in rows]
    if test == "shear":
        angles = [float(r[1]) for r in rows]
        assert min(angles) == pytest.approx(-0.1396263, rel=1e-6)
        assert max(angles) == pytest.approx(0.1396263, rel=1e-6)
    else:
        assert strains[0] == 0.0 and max(strains) > 0.09


def test_free_edges_show_the_testers_edge_effect():
    # Soft shear against stiff fibres: with free side edges the clamp force departs from the
    # law by far more than with the sides guided (the default), the solver's error alone.
    m = LIBRARY / "white-dots-on-blk.toml"
    guided = json.loads(kes(m, "--test", "shear", "--json").stdout)
    free = json.loads(kes(m, "--test", "shear", "--json", "--free-edges").stdout)
    assert guided["material_max_pct"] < 1e-4
    assert free["material_max_pct"] > 0.1


def test_plot_is_written(tmp_path):
    png = tmp_path / "kes.png"
    r = kes(LIBRARY / "11oz-black-denim.toml", "--test", "warp", "--measured",
            MEASURED / "11oz-black-denim.csv", "--plot", png)
    assert r.returncode == 0, r.stderr
    assert png.stat().st_size > 10000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("text, line, words", [
    ("strain,stress\n0,0\n", 1, "header"),
    ("test,strain,stress\nweft,0,0\nweft,x,1\n", 3, "not a number"),
    ("test,strain,stress\nweft,0.1,0\nweft,0.05,1\n", 3, "increase"),
    ("test,strain,stress\nbias,0,0\n", 2, "unknown test"),
])
def test_bad_measured_csv_exits_2_with_file_and_line(tmp_path, text, line, words):
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    r = kes(LIBRARY / "11oz-black-denim.toml", "--test", "weft", "--measured", bad)
    assert r.returncode == 2
    assert f"{bad}:{line}:" in r.stderr and words in r.stderr


def test_bad_material_and_test_name_exit_2(tmp_path):
    m = tmp_path / "m.toml"
    m.write_text('name = "x"\nareal_density = 0.2\n[weft]\nknots = [0.0]\nB = [[0, -5, 0, 0]]\n')
    r = kes(m, "--test", "weft")
    assert r.returncode == 2 and str(m) in r.stderr
    r = kes(LIBRARY / "11oz-black-denim.toml", "--test", "bias")
    assert r.returncode == 2 and "unknown test 'bias'" in r.stderr


# hapticloth-kes checks its output paths before the test runs (exit 2, the option named).
def test_plot_to_a_missing_folder_is_exit_2_before_the_test(tmp_path):
    png = tmp_path / "missing" / "kes.png"
    r = kes(LIBRARY / "11oz-black-denim.toml", "--test", "warp", "--plot", png)
    assert "Traceback" not in r.stdout + r.stderr, r.stderr
    assert r.returncode == 2
    assert f"--plot: cannot write {png}: the folder {png.parent} does not exist" in r.stderr, r.stderr
    assert r.stdout == ""  # no test was run


def kes_plot(*args) -> subprocess.CompletedProcess:
    """The plot step alone, as hapticloth-kes runs it (the venv's python -m hapticloth.kes_plot)."""
    import sys

    return subprocess.run([sys.executable, "-m", "hapticloth.kes_plot", *map(str, args)],
                          capture_output=True, text=True, timeout=120)


def sim_csv(tmp_path) -> Path:
    out = tmp_path / "sim.csv"
    r = kes(LIBRARY / "11oz-black-denim.toml", "--test", "warp", "--csv", out)
    assert r.returncode == 0, r.stderr
    return out


KES_PLOT_ERROR = "hapticloth-kes-plot: --plot {png}: cannot write: the folder {folder} does not exist"


def test_kes_plot_step_exits_2_for_a_missing_folder(tmp_path):
    png = tmp_path / "missing" / "kes.png"
    r = kes_plot(sim_csv(tmp_path), png, "--test", "warp")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip() == KES_PLOT_ERROR.format(png=png, folder=png.parent)


def test_kes_plot_step_names_a_bad_csv(tmp_path):
    png = tmp_path / "kes.png"
    bad = tmp_path / "bad.csv"
    bad.write_text("strain,stress_n_per_m,material_n_per_m\n0,0,0\n0.1,x,1\n")
    r = kes_plot(bad, png, "--test", "warp")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"{bad}:3: stress_n_per_m 'x' is not a number" in r.stderr
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"\xff\xfe\x00" * 100)
    r = kes_plot(binary, png, "--test", "warp")
    assert r.returncode == 2 and f"{binary}: not a text file" in r.stderr
    r = kes_plot(sim_csv(tmp_path), png, "--test", "warp", "--measured", tmp_path / "nope.csv")
    assert r.returncode == 2 and f"{tmp_path / 'nope.csv'}: no such file" in r.stderr
    assert not png.exists()
