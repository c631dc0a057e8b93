"""tools/portable_isa.py: it names a function outside the levels' namespaces that uses AVX, and
passes the same instructions inside the level allowed them (a program compiled here with g++)."""
import pathlib
import subprocess
import sys

import pytest

TOP = pathlib.Path(__file__).resolve().parents[2]
SOURCE = r"""
#include <immintrin.h>
namespace hapticloth::cloth::simd_avx2 {
__attribute__((target("avx2,fma"), noinline)) double inside(const double* p) {
  __m256d a = _mm256_loadu_pd(p);
  return _mm256_cvtsd_f64(_mm256_fmadd_pd(a, a, a));
}
__attribute__((target("avx512f"), noinline)) double too_wide(const double* p) {
  return _mm512_reduce_add_pd(_mm512_loadu_pd(p));
}
}
__attribute__((target("avx2"), noinline)) double outside(const double* p) {
  return _mm256_cvtsd_f64(_mm256_add_pd(_mm256_loadu_pd(p), _mm256_loadu_pd(p + 4)));
}
__attribute__((noinline)) double plain(const double* p) { return p[0] + p[1]; }
int main(int argc, char**) {
  double d[8] = {1, 2, 3, 4, 5, 6, 7, 8};
  if (argc > 5) return static_cast<int>(hapticloth::cloth::simd_avx2::inside(d) +
                                        hapticloth::cloth::simd_avx2::too_wide(d) + outside(d));
  return static_cast<int>(plain(d)) - 3;
}
"""


def run_check(tmp_path, source):
    src = tmp_path / "prog.cpp"
    src.write_text(source)
    exe = tmp_path / "prog"
    subprocess.run(["g++", "-O2", "-march=x86-64-v2", "-o", str(exe), str(src)], check=True)
    return subprocess.run([sys.executable, str(TOP / "tools/portable_isa.py"), str(exe)],
                          capture_output=True, text=True, timeout=60)


@pytest.mark.skipif(subprocess.run(["uname", "-m"], capture_output=True, text=True).stdout.strip() != "x86_64",
                    reason="x86-64 instruction levels")
def test_names_the_functions_outside_their_level(tmp_path):
    r = run_check(tmp_path, SOURCE)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "outside(" in r.stdout  # AVX outside any level
    assert "too_wide(" in r.stdout  # AVX-512 in the AVX2 level
    assert "inside(" not in r.stdout and "plain(" not in r.stdout


@pytest.mark.skipif(subprocess.run(["uname", "-m"], capture_output=True, text=True).stdout.strip() != "x86_64",
                    reason="x86-64 instruction levels")
def test_passes_a_program_whose_avx_is_in_its_level(tmp_path):
    clean = SOURCE.replace('__attribute__((target("avx2"), noinline)) double outside',
                           '__attribute__((noinline)) double outside')
    clean = clean.replace("_mm256_cvtsd_f64(_mm256_add_pd(_mm256_loadu_pd(p), _mm256_loadu_pd(p + 4)))",
                          "p[0] + p[4]")
    clean = clean.replace('__attribute__((target("avx512f"), noinline)) double too_wide(const double* p) {\n'
                          '  return _mm512_reduce_add_pd(_mm512_loadu_pd(p));',
                          '__attribute__((noinline)) double too_wide(const double* p) {\n  return p[7];')
    r = run_check(tmp_path, clean)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "portable" in r.stdout
