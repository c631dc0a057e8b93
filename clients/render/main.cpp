// hapticloth-render: pictures of a cloth run, offscreen (OSMesa), from an LCM log written by
// hapticloth-server --lcm-log or live from a server over zenoh. One PNG (--snapshot), a PNG
// sequence (--frames) or an MP4 (--mp4, with ffmpeg).
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <tuple>

#include "cli_checks.hpp"

#include "render/recording.hpp"
#include "render/renderer.hpp"
#include "render/strain.hpp"
#include "render/zenoh_source.hpp"

extern char** environ;

namespace {

using namespace hapticloth::render;
namespace fs = std::filesystem;

std::optional<Eigen::Vector3d> parse_vec(const std::string& s) {
  double v[3];
  char end;
  if (std::sscanf(s.c_str(), "%lf,%lf,%lf%c", &v[0], &v[1], &v[2], &end) != 3) return std::nullopt;
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

// Strain range of the colour bar: the 99th percentile of |strain| over the frames drawn, rounded
// up to 1, 2, 2.5 or 5 times a power of ten (clean labels), at least 0.01%.
double auto_strain_range(const Recording& rec, const std::vector<std::size_t>& frames, StrainComponent c) {
  const StrainField field(rec.scene);
  std::vector<hapticloth::cloth::Strains> eps;
  std::vector<double> a;
  for (std::size_t i : frames) {
    field.compute(rec.frames[i].positions, eps);
    for (const auto& e : eps) {
      const double v = std::abs(component(e, c));
      if (std::isfinite(v)) a.push_back(v);
    }
  }
  double r = 1e-4;
  if (!a.empty()) {
    const std::size_t k = static_cast<std::size_t>(0.99 * (a.size() - 1));
    std::nth_element(a.begin(), a.begin() + static_cast<long>(k), a.end());
    r = std::max(r, a[k]);
  }
  const double p = std::pow(10.0, std::floor(std::log10(r)));
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * p >= r * (1 - 1e-9)) return m * p;
  return 10 * p;
}

std::string find_on_path(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream ss(path ? path : "");
  for (std::string dir; std::getline(ss, dir, ':');) {
    const fs::path p = fs::path(dir.empty() ? "." : dir) / name;
    if (::access(p.c_str(), X_OK) == 0) return p.string();
  }
  return "";
}

int run(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid;
  if (posix_spawn(&pid, args[0].c_str(), nullptr, nullptr, argv.data(), environ) != 0) return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) < 0) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"hapticloth-render: offscreen pictures of a cloth run (OSMesa), from an LCM log or live over zenoh"};
  std::string log, endpoint, server = "default";
  std::string snapshot, frames_dir, mp4, color = "weave", size = "1280x720";
  std::string eye_s, target_s, up_s;
  double time = NAN, fps = 30.0, start = NAN, end = NAN, fov = 35.0, strain_range = 0.0;
  double timeout = 5.0, duration = 10.0;
  int supersample = 2;
  bool no_fingers = false, no_colorbar = false, no_label = false, no_refined_edges = false;
  Style style;
  auto* o_log = cli.add_option("--log", log, "LCM log written by hapticloth-server --lcm-log");
  auto* o_zen = cli.add_option("--zenoh", endpoint, "live: connect to the server's zenoh endpoint (e.g. tcp/127.0.0.1:7447)");
  o_log->excludes(o_zen);
  cli.add_option("--server", server, "live: server name, key expressions hapticloth/<name>/... (default: default)");
  cli.add_option("--timeout", timeout, "live: seconds to wait for the scene and the first cloth state (default 5)")
      ->check(hapticloth::opts::positive(3600.0, "s"));
  cli.add_option("--duration", duration, "live: seconds to collect for --frames/--mp4 (default 10; ends early when the stream stops)")
      ->check(hapticloth::opts::positive(1e6, "s"));
  cli.add_option("--snapshot", snapshot, "write one frame to this PNG")->check(hapticloth::opts::writable_file());
  cli.add_option("--time", time, "snapshot: the frame nearest this session time, s (default: the last; live: the first at or after it)")
      ->check(hapticloth::opts::number_in(0.0, 1e9, false, "s"));
  cli.add_option("--frames", frames_dir, "write a PNG sequence frame_00000.png, ... into this directory");
  cli.add_option("--fps", fps, "frames per second of session time for --frames/--mp4 (default 30)")->check(hapticloth::opts::number_in(0.1, 1000.0));
  cli.add_option("--start", start, "first session time of --frames/--mp4, s (default: the first state)")
      ->check(hapticloth::opts::number_in(0.0, 1e9, false, "s"));
  cli.add_option("--end", end, "last session time of --frames/--mp4, s (default: the last state)")
      ->check(hapticloth::opts::number_in(0.0, 1e9, false, "s"));
  cli.add_option("--mp4", mp4, "encode the frames into this MP4 with ffmpeg (skipped with a message if ffmpeg is missing)")
      ->check(hapticloth::opts::writable_file());
  cli.add_option("--color", color, "weave (texture) | weft | warp | shear (eq. 4 strain per triangle)")
      ->check(CLI::IsMember({"weave", "weft", "warp", "shear"}));
  cli.add_option("--strain-range", strain_range, "strain at the ends of the colour bar, e.g. 0.02 = 2% (default: from the frames drawn)")
      ->check(hapticloth::opts::positive(10.0));
  cli.add_option("--weave-pitch", style.weave_pitch, "m of cloth per repeat of the weave texture, 4 threads (default 0.02)")
      ->check(hapticloth::opts::positive(10.0, "m"));
  cli.add_option("--eye", eye_s, "camera position X,Y,Z (m, scene frame; default: framed from the mesh's bounding box)");
  cli.add_option("--target", target_s, "point looked at X,Y,Z (default: the bounding box centre)");
  cli.add_option("--up", up_s, "camera up direction X,Y,Z (default 0,0,1)");
  cli.add_option("--fov", fov, "vertical field of view, degrees (default 35)")->check(hapticloth::opts::number_in(1.0, 170.0, false, "degrees"));
  cli.add_option("--size", size, "picture size WxH in pixels (default 1280x720)");
  cli.add_option("--supersample", supersample, "draw at N times the size and average down (default 2)")->check(CLI::Range(1, 4));
  cli.add_option("--finger-radius", style.finger_radius, "fingertip sphere radius, m (default 0.008)")
      ->check(hapticloth::opts::positive(1.0, "m"));
  cli.add_option("--force-scale", style.force_scale, "force arrow length per newton, m/N (default 0.02; 0: no arrows)")
      ->check(hapticloth::opts::number_in(0.0, 10.0, false, "m/N"));
  cli.add_flag("--no-fingers", no_fingers, "do not draw the fingertips");
  cli.add_flag("--no-colorbar", no_colorbar, "do not draw the colour bar");
  cli.add_flag("--no-label", no_label, "do not write time and forces on the picture");
  cli.add_flag("--no-refined-edges", no_refined_edges,
               "do not draw the edges of the refined cloth under the fingertips (it is drawn either way)");
  if (const int rc = hapticloth::opts::parse(cli, argc, argv); rc >= 0) return rc;

  const std::string me = "hapticloth-render: ";
  if (log.empty() && endpoint.empty()) {
    std::cerr << me << "give --log FILE or --zenoh ENDPOINT\n";
    return 2;
  }
  if (snapshot.empty() && frames_dir.empty() && mp4.empty()) {
    std::cerr << me << "nothing to write: give --snapshot, --frames or --mp4\n";
    return 2;
  }
  int width = 0, height = 0;
  char xc = 0, extra = 0;
  if (std::sscanf(size.c_str(), "%d%c%d%c", &width, &xc, &height, &extra) != 3 || xc != 'x') {
    std::cerr << me << "--size must be WxH, e.g. 1280x720\n";
    return 2;
  }
  std::optional<Eigen::Vector3d> eye, target, up;
  for (auto [s, v, name] : {std::tuple{&eye_s, &eye, "--eye"}, {&target_s, &target, "--target"}, {&up_s, &up, "--up"}}) {
    if (s->empty()) continue;
    *v = parse_vec(*s);
    if (!*v) {
      std::cerr << me << name << " must be X,Y,Z\n";
      return 2;
    }
  }
  parse_color_mode(color, style.color);
  style.fingers = !no_fingers;
  style.colorbar = !no_colorbar;
  style.label = !no_label;
  style.refined_edges = !no_refined_edges;

  std::string mp4_skip;
  if (!mp4.empty() && find_on_path("ffmpeg").empty()) {
    mp4_skip = "ffmpeg is not installed (not on PATH): skipping " + mp4 + " (apt-get install ffmpeg)";
    if (snapshot.empty() && frames_dir.empty()) {
      std::cerr << me << mp4_skip << "\n";
      return 0;
    }
  }

  // --- the run
  Recording rec;
  const std::string source = log.empty() ? "hapticloth/" + server + " at " + endpoint : log;
  try {
    if (!log.empty()) {
      rec = read_lcm_log(log);
    } else {
      ZenohCollect z;
      z.endpoint = endpoint;
      z.server = server;
      z.timeout = timeout;
      z.duration = duration;
      z.single = frames_dir.empty() && mp4.empty();
      z.until_time = std::isnan(time) ? -1.0 : time;
      rec = collect_zenoh(z);
    }
  } catch (const InputError& e) {
    std::cerr << me << e.what() << "\n";
    return log.empty() ? 3 : 2;
  } catch (const std::exception& e) {
    std::cerr << me << source << ": " << e.what() << "\n";
    return log.empty() ? 3 : 2;
  }
  if (rec.frames.empty()) {
    std::cerr << me << source << ": no cloth_state_t message fits the mesh (" << rec.dropped << " of another size)\n";
    return 2;
  }

  // --- what to draw and how
  std::vector<std::size_t> snap, seq;
  if (!snapshot.empty()) snap.push_back(std::isnan(time) ? rec.frames.size() - 1 : rec.frame_near(time));
  if (!frames_dir.empty() || (!mp4.empty() && mp4_skip.empty())) {
    const double t0 = std::isnan(start) ? rec.frames.front().time : start;
    const double t1 = std::isnan(end) ? rec.frames.back().time : end;
    for (long k = 0; t0 + k / fps <= t1 + 1e-9; ++k) seq.push_back(rec.frame_near(t0 + k / fps));
    if (seq.empty()) {
      std::cerr << me << "--start " << t0 << " is after --end " << t1 << "\n";
      return 2;
    }
  }
  const StrainComponent comp = style.color == ColorMode::Warp ? StrainComponent::Warp
                             : style.color == ColorMode::Shear ? StrainComponent::Shear
                                                               : StrainComponent::Weft;
  try {
    Renderer renderer(width, height, supersample);
    // One camera for a sequence (framed on all its frames), its own for a snapshot.
    auto camera_for = [&](const std::vector<std::size_t>& idx) {
      std::vector<Vec3f> pts;
      for (std::size_t i : idx) {
        const auto p = framing_points(rec.frames[i], rec.haptics_at(rec.frames[i].time), style);
        pts.insert(pts.end(), p.begin(), p.end());
      }
      const Viewport vp = renderer.scene_viewport(style);
      Camera cam = frame_points(pts, fov, static_cast<double>(vp.width) / vp.height);
      if (eye) cam.eye = *eye;
      if (target) cam.target = *target;
      if (up) cam.up = *up;
      return cam;
    };
    auto set_range = [&](const std::vector<std::size_t>& idx) {
      if (style.color == ColorMode::Weave) return;
      style.strain_range = strain_range > 0 ? strain_range : auto_strain_range(rec, idx, comp);
    };
    auto draw = [&](std::size_t i, const Camera& cam) {
      const ClothFrame& f = rec.frames[i];
      return renderer.render(rec.scene, f, rec.haptics_at(f.time), cam, style);
    };
    const char* range_note = strain_range > 0 ? "" : " (auto)";
    if (!snap.empty()) {
      set_range(snap);
      const ClothFrame& f = rec.frames[snap[0]];
      write_png(snapshot, draw(snap[0], camera_for(snap)));
      std::cout << snapshot << ": t = " << f.time << " s (step " << f.step << "), " << width << "x" << height << ", "
                << color;
      if (style.color != ColorMode::Weave) std::cout << ", strain range +-" << 100 * style.strain_range << "%" << range_note;
      std::cout << "\n";
    }
    if (!seq.empty()) {
      std::error_code ec;
      fs::path dir = frames_dir;
      bool temp = false;
      if (dir.empty()) {
        char tmpl[] = "/tmp/hapticloth-render-XXXXXX";
        if (!::mkdtemp(tmpl)) throw std::runtime_error("cannot make a temporary directory for the frames");
        dir = tmpl;
        temp = true;
      } else {
        fs::create_directories(dir, ec);
        if (ec) throw std::runtime_error(dir.string() + ": cannot create (" + ec.message() + ")");
      }
      set_range(seq);
      const Camera cam = camera_for(seq);
      char name[32];
      for (std::size_t k = 0; k < seq.size(); ++k) {
        std::snprintf(name, sizeof name, "frame_%05zu.png", k);
        write_png((dir / name).string(), draw(seq[k], cam));
      }
      std::cout << (temp ? std::string("frames") : dir.string()) << ": " << seq.size() << " frames at " << fps
                << " fps, t = " << rec.frames[seq.front()].time << " .. " << rec.frames[seq.back()].time << " s, " << color;
      if (style.color != ColorMode::Weave) std::cout << ", strain range +-" << 100 * style.strain_range << "%" << range_note;
      std::cout << "\n";
      int rc = 0;
      if (!mp4.empty() && mp4_skip.empty()) {
        char rate[32];
        std::snprintf(rate, sizeof rate, "%g", fps);
        rc = run({find_on_path("ffmpeg"), "-y", "-loglevel", "error", "-framerate", rate, "-i",
                  (dir / "frame_%05d.png").string(), "-c:v", "libx264", "-pix_fmt", "yuv420p", "-vf",
                  "pad=ceil(iw/2)*2:ceil(ih/2)*2", mp4});
        if (rc == 0) std::cout << mp4 << ": " << seq.size() << " frames\n";
        else std::cerr << me << "ffmpeg failed (exit " << rc << ") writing " << mp4 << "\n";
      }
      if (temp) fs::remove_all(dir, ec);
      if (rc != 0) return 1;
    }
  } catch (const std::exception& e) {
    std::cerr << me << e.what() << "\n";
    return 1;
  }
  if (!mp4_skip.empty()) std::cerr << me << mp4_skip << "\n";
  return 0;
}
