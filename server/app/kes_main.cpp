// hapticloth-kes: the simulated Kawabata (KES-F) tensile and shear tests of a material file.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sys/wait.h>

#include <unistd.h>

#include "cli_checks.hpp"

#include "app/kes.hpp"
#include "app/material_file.hpp"
#include "app/toml_file.hpp"

namespace {

// The plot is drawn by the Python package (matplotlib in the project's .venv).
std::string python_interpreter() {
  if (const char* p = std::getenv("HAPTICLOTH_PYTHON")) return p;
  return std::string(HAPTICLOTH_SOURCE_DIR) + "/.venv/bin/python";
}

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

int main(int argc, char** argv) {
  using namespace hapticloth;
  CLI::App cli{"hapticloth-kes: simulated Kawabata tensile and shear tests of a material"};
  std::string material_path, test_name, measured_path, csv_path, plot_path;
  bool json = false;
  app::KesOptions opt;
  cli.add_option("material", material_path, "material file (TOML)")->required();
  cli.add_option("--test", test_name, "weft, warp or shear")->required();
  cli.add_option("--measured", measured_path, "measured CSV (test,strain,stress) to compare with");
  cli.add_option("--csv", csv_path, "write the simulated curve as CSV")->check(opts::writable_file());
  cli.add_option("--plot", plot_path, "write a PNG: measured points, material law, simulated test")
      ->check(opts::writable_file());
  cli.add_flag("--json", json, "print the result as one JSON object");
  cli.add_option("--steps", opt.load_steps, "quasi-static load steps per branch (default 30)")
      ->check(CLI::Range(1, 10000));
  cli.add_option("--cells-per-cm", opt.cells_per_cm, "specimen mesh resolution (default 2)")->check(CLI::Range(1, 50));
  cli.add_option("--max-strain", opt.max_strain, "tensile: largest strain (default: the law's max_strain)")
      ->check(opts::positive(1.0));
  cli.add_option("--max-shear-deg", opt.max_shear_deg, "shear: sweep to +- this angle (default 8)")
      ->check(opts::positive(45.0, "degrees"));
  cli.add_option("--tension", opt.lateral_tension, "shear: lateral tension, N/m (default 9.81 = 10 gf/cm)")
      ->check(opts::number_in(0.0, 1e4, false, "N/m"));
  cli.add_flag("--free-edges", opt.free_edges, "shear: free side edges, as on the tester (docs/kes.md)");
  if (const int rc = opts::parse(cli, argc, argv); rc >= 0) return rc;

  app::KesTest test;
  cloth::Material mat;
  app::KesMeasured measured;
  try {
    test = app::parse_kes_test(test_name);
    mat = app::load_material(material_path);
    if (!measured_path.empty()) measured = app::load_measured(measured_path, test);
  } catch (const std::exception& e) {
    std::cerr << "hapticloth-kes: " << e.what() << "\n";
    return 2;
  }
  app::KesResult r;
  try {
    r = app::run_kes(mat, test, opt);
  } catch (const std::invalid_argument& e) {
    std::cerr << "hapticloth-kes: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "hapticloth-kes: " << e.what() << "\n";
    return 1;
  }
  if (!measured_path.empty()) app::compare_measured(r, measured);
  std::cout << (json ? app::kes_to_json(r) + "\n" : app::kes_to_text(r));
  if (!csv_path.empty()) {
    std::ofstream out(csv_path);
    out << app::kes_to_csv(r);
    if (!out) {
      std::cerr << "hapticloth-kes: cannot write " << csv_path << "\n";
      return 1;
    }
  }
  if (!plot_path.empty()) {
    namespace fs = std::filesystem;
    const fs::path tmp = fs::temp_directory_path() / ("hapticloth-kes-" + std::to_string(::getpid()) + ".csv");
    {
      std::ofstream out(tmp);
      out << app::kes_to_csv(r);
    }
    std::string cmd = shell_quote(python_interpreter()) + " -m hapticloth.kes_plot " +
                      shell_quote(tmp.string()) + " " + shell_quote(plot_path) + " --test " +
                      app::to_string(test) + " --title " + shell_quote(mat.name);
    if (!measured_path.empty()) cmd += " --measured " + shell_quote(measured_path);
    const int rc = std::system(cmd.c_str());
    fs::remove(tmp);
    if (WIFEXITED(rc) && WEXITSTATUS(rc) == 2) return 2;  // a user error, already said in one line
    if (rc != 0) {
      std::cerr << "hapticloth-kes: the plot failed (" << cmd << ")\n";
      return 1;
    }
  }
  return r.converged ? 0 : 1;
}
