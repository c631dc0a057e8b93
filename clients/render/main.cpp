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
#include <variant>

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

// Every option, as CLI11 writes them.
struct Options {
  std::string log, endpoint, server = "default";
  std::string snapshot, frames_dir, mp4, color = "weave", size = "1280x720";
  std::string eye_s, target_s, up_s;
  double time = NAN, fps = 30.0, start = NAN, end = NAN, fov = 35.0, strain_range = 0.0;
  double timeout = 5.0, duration = 10.0;
  int supersample = 2;
  bool no_fingers = false, no_colorbar = false, no_label = false, no_refined_edges = false;
  Style style;
};

void add_source_options(CLI::App& cli, Options& o) {
  using namespace hapticloth::opts;
  auto* o_log = cli.add_option("--log", o.log, "LCM log written by hapticloth-server --lcm-log");
  auto* o_zen = cli.add_option("--zenoh", o.endpoint, "live: connect to the server's zenoh endpoint (e.g. tcp/127.0.0.1:7447)");
  o_log->excludes(o_zen);
  cli.add_option("--server", o.server, "live: server name, key expressions hapticloth/<name>/... (default: default)");
  cli.add_option("--timeout", o.timeout, "live: seconds to wait for the scene and the first cloth state (default 5)")
      ->check(positive(3600.0, "s"));
  cli.add_option("--duration", o.duration, "live: seconds to collect for --frames/--mp4 (default 10; ends early when the stream stops)")
      ->check(positive(1e6, "s"));
}

void add_output_options(CLI::App& cli, Options& o) {
  using namespace hapticloth::opts;
  cli.add_option("--snapshot", o.snapshot, "write one frame to this PNG")->check(writable_file());
  cli.add_option("--time", o.time, "snapshot: the frame nearest this session time, s (default: the last; live: the first at or after it)")
      ->check(number_in(0.0, 1e9, false, "s"));
  cli.add_option("--frames", o.frames_dir, "write a PNG sequence frame_00000.png, ... into this directory");
  cli.add_option("--fps", o.fps, "frames per second of session time for --frames/--mp4 (default 30)")->check(number_in(0.1, 1000.0));
  cli.add_option("--start", o.start, "first session time of --frames/--mp4, s (default: the first state)")
      ->check(number_in(0.0, 1e9, false, "s"));
  cli.add_option("--end", o.end, "last session time of --frames/--mp4, s (default: the last state)")
      ->check(number_in(0.0, 1e9, false, "s"));
  cli.add_option("--mp4", o.mp4, "encode the frames into this MP4 with ffmpeg (skipped with a message if ffmpeg is missing)")
      ->check(writable_file());
}

void add_picture_options(CLI::App& cli, Options& o) {
  using namespace hapticloth::opts;
  cli.add_option("--color", o.color, "weave (texture) | weft | warp | shear (eq. 4 strain per triangle)")
      ->check(CLI::IsMember({"weave", "weft", "warp", "shear"}));
  cli.add_option("--strain-range", o.strain_range, "strain at the ends of the colour bar, e.g. 0.02 = 2% (default: from the frames drawn)")
      ->check(positive(10.0));
  cli.add_option("--weave-pitch", o.style.weave_pitch, "m of cloth per repeat of the weave texture, 4 threads (default 0.02)")
      ->check(positive(10.0, "m"));
  cli.add_option("--eye", o.eye_s, "camera position X,Y,Z (m, scene frame; default: framed from the mesh's bounding box)");
  cli.add_option("--target", o.target_s, "point looked at X,Y,Z (default: the bounding box centre)");
  cli.add_option("--up", o.up_s, "camera up direction X,Y,Z (default 0,0,1)");
  cli.add_option("--fov", o.fov, "vertical field of view, degrees (default 35)")->check(number_in(1.0, 170.0, false, "degrees"));
  cli.add_option("--size", o.size, "picture size WxH in pixels (default 1280x720)");
  cli.add_option("--supersample", o.supersample, "draw at N times the size and average down (default 2)")->check(CLI::Range(1, 4));
  cli.add_option("--finger-radius", o.style.finger_radius, "fingertip sphere radius, m (default 0.008)")
      ->check(positive(1.0, "m"));
  cli.add_option("--force-scale", o.style.force_scale, "force arrow length per newton, m/N (default 0.02; 0: no arrows)")
      ->check(number_in(0.0, 10.0, false, "m/N"));
  cli.add_flag("--no-fingers", o.no_fingers, "do not draw the fingertips");
  cli.add_flag("--no-colorbar", o.no_colorbar, "do not draw the colour bar");
  cli.add_flag("--no-label", o.no_label, "do not write time and forces on the picture");
  cli.add_flag("--no-refined-edges", o.no_refined_edges,
               "do not draw the edges of the refined cloth under the fingertips (it is drawn either way)");
}

void add_options(CLI::App& cli, Options& o) {
  add_source_options(cli, o);
  add_output_options(cli, o);
  add_picture_options(cli, o);
}

const std::string me = "hapticloth-render: ";

// Says what is wrong on stderr and gives the exit code.
template <class... Parts>
int fail(int code, const Parts&... parts) {
  ((std::cerr << me) << ... << parts) << "\n";
  return code;
}

// What the options ask for, checked: the picture's size, the camera's overrides and whether the
// MP4 is skipped (ffmpeg missing).
struct Job {
  int width = 0, height = 0;
  std::optional<Eigen::Vector3d> eye, target, up;
  std::string mp4_skip;
  bool sequence = false;  // --frames, or an MP4 that is not skipped
};

// The job, or the exit code after saying what is wrong (0: nothing to do but skip the MP4).
std::variant<Job, int> check_options(Options& o) {
  if (o.log.empty() && o.endpoint.empty()) return fail(2, "give --log FILE or --zenoh ENDPOINT");
  if (o.snapshot.empty() && o.frames_dir.empty() && o.mp4.empty())
    return fail(2, "nothing to write: give --snapshot, --frames or --mp4");
  Job j;
  char xc = 0, extra = 0;
  if (std::sscanf(o.size.c_str(), "%d%c%d%c", &j.width, &xc, &j.height, &extra) != 3 || xc != 'x')
    return fail(2, "--size must be WxH, e.g. 1280x720");
  for (auto [s, v, name] : {std::tuple{&o.eye_s, &j.eye, "--eye"}, {&o.target_s, &j.target, "--target"},
                            {&o.up_s, &j.up, "--up"}}) {
    if (s->empty()) continue;
    *v = parse_vec(*s);
    if (!*v) return fail(2, name, " must be X,Y,Z");
  }
  parse_color_mode(o.color, o.style.color);
  o.style.fingers = !o.no_fingers;
  o.style.colorbar = !o.no_colorbar;
  o.style.label = !o.no_label;
  o.style.refined_edges = !o.no_refined_edges;
  if (!o.mp4.empty() && find_on_path("ffmpeg").empty()) {
    j.mp4_skip = "ffmpeg is not installed (not on PATH): skipping " + o.mp4 + " (apt-get install ffmpeg)";
    if (o.snapshot.empty() && o.frames_dir.empty()) return fail(0, j.mp4_skip);
  }
  j.sequence = !o.frames_dir.empty() || (!o.mp4.empty() && j.mp4_skip.empty());
  return j;
}

// The run, from the log or live over zenoh; or the exit code after saying why not (3: the
// server did not answer).
std::variant<Recording, int> read_recording(const Options& o) {
  const std::string source = o.log.empty() ? "hapticloth/" + o.server + " at " + o.endpoint : o.log;
  const int failed = o.log.empty() ? 3 : 2;
  Recording rec;
  try {
    if (!o.log.empty()) {
      rec = read_lcm_log(o.log);
    } else {
      ZenohCollect z;
      z.endpoint = o.endpoint;
      z.server = o.server;
      z.timeout = o.timeout;
      z.duration = o.duration;
      z.single = o.frames_dir.empty() && o.mp4.empty();
      z.until_time = std::isnan(o.time) ? -1.0 : o.time;
      rec = collect_zenoh(z);
    }
  } catch (const InputError& e) {
    return fail(failed, e.what());
  } catch (const std::exception& e) {
    return fail(failed, source, ": ", e.what());
  }
  if (rec.frames.empty())
    return fail(2, source, ": no cloth_state_t message fits the mesh (", rec.dropped, " of another size)");
  return rec;
}

// The frames of the sequence, one every 1/fps of session time from --start to --end (none when
// --start is after --end).
std::vector<std::size_t> sequence_frames(const Options& o, const Recording& rec) {
  const double t0 = std::isnan(o.start) ? rec.frames.front().time : o.start;
  const double t1 = std::isnan(o.end) ? rec.frames.back().time : o.end;
  std::vector<std::size_t> seq;
  for (long k = 0; t0 + k / o.fps <= t1 + 1e-9; ++k) seq.push_back(rec.frame_near(t0 + k / o.fps));
  if (seq.empty()) std::cerr << me << "--start " << t0 << " is after --end " << t1 << "\n";
  return seq;
}

// Draws frames of the recording: one camera framed on all the frames drawn together, and the
// strain colour bar's range from them unless --strain-range gives it.
class Drawing {
 public:
  Drawing(const Options& o, const Job& j, const Recording& rec)
      : o_(o), job_(j), rec_(rec), style_(o.style), renderer_(j.width, j.height, o.supersample) {}

  // Frames `idx` with their camera and colour range; calls write(k, picture) for each.
  template <class Write>
  void draw(const std::vector<std::size_t>& idx, Write write) {
    set_range(idx);
    const Camera cam = camera_for(idx);
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const ClothFrame& f = rec_.frames[idx[k]];
      write(k, renderer_.render(rec_.scene, f, rec_.haptics_at(f.time), cam, style_));
    }
  }

  // ", weft, strain range +-2% (auto)": what the colours mean, for the line written after.
  std::string colour_note() const {
    std::ostringstream s;
    s << ", " << o_.color;
    if (style_.color != ColorMode::Weave)
      s << ", strain range +-" << 100 * style_.strain_range << "%" << (o_.strain_range > 0 ? "" : " (auto)");
    return s.str();
  }

 private:
  Camera camera_for(const std::vector<std::size_t>& idx) {
    std::vector<Vec3f> pts;
    for (std::size_t i : idx) {
      const auto p = framing_points(rec_.frames[i], rec_.haptics_at(rec_.frames[i].time), style_);
      pts.insert(pts.end(), p.begin(), p.end());
    }
    const Viewport vp = renderer_.scene_viewport(style_);
    Camera cam = frame_points(pts, o_.fov, static_cast<double>(vp.width) / vp.height);
    if (job_.eye) cam.eye = *job_.eye;
    if (job_.target) cam.target = *job_.target;
    if (job_.up) cam.up = *job_.up;
    return cam;
  }

  void set_range(const std::vector<std::size_t>& idx) {
    if (style_.color == ColorMode::Weave) return;
    const StrainComponent c = style_.color == ColorMode::Warp    ? StrainComponent::Warp
                              : style_.color == ColorMode::Shear ? StrainComponent::Shear
                                                                 : StrainComponent::Weft;
    style_.strain_range = o_.strain_range > 0 ? o_.strain_range : auto_strain_range(rec_, idx, c);
  }

  const Options& o_;
  const Job& job_;
  const Recording& rec_;
  Style style_;
  Renderer renderer_;
};

void write_snapshot(const Options& o, const Job& j, const Recording& rec, Drawing& d) {
  const std::size_t i = std::isnan(o.time) ? rec.frames.size() - 1 : rec.frame_near(o.time);
  d.draw({i}, [&](std::size_t, const auto& picture) { write_png(o.snapshot, picture); });
  const ClothFrame& f = rec.frames[i];
  std::cout << o.snapshot << ": t = " << f.time << " s (step " << f.step << "), " << j.width << "x" << j.height
            << d.colour_note() << "\n";
}

// The folder the sequence is written to: --frames, or a temporary one for the MP4 alone.
fs::path frames_folder(const Options& o) {
  if (o.frames_dir.empty()) {
    char tmpl[] = "/tmp/hapticloth-render-XXXXXX";
    if (!::mkdtemp(tmpl)) throw std::runtime_error("cannot make a temporary directory for the frames");
    return tmpl;
  }
  std::error_code ec;
  fs::create_directories(o.frames_dir, ec);
  if (ec) throw std::runtime_error(o.frames_dir + ": cannot create (" + ec.message() + ")");
  return o.frames_dir;
}

// ffmpeg's exit code encoding the sequence in `dir` into --mp4.
int encode_mp4(const Options& o, const fs::path& dir, std::size_t frames) {
  char rate[32];
  std::snprintf(rate, sizeof rate, "%g", o.fps);
  const int rc = run({find_on_path("ffmpeg"), "-y", "-loglevel", "error", "-framerate", rate, "-i",
                      (dir / "frame_%05d.png").string(), "-c:v", "libx264", "-pix_fmt", "yuv420p", "-vf",
                      "pad=ceil(iw/2)*2:ceil(ih/2)*2", o.mp4});
  if (rc == 0) std::cout << o.mp4 << ": " << frames << " frames\n";
  else std::cerr << me << "ffmpeg failed (exit " << rc << ") writing " << o.mp4 << "\n";
  return rc;
}

// The PNG sequence (and the MP4 from it): 0, or 1 when ffmpeg failed.
int write_sequence(const Options& o, const Job& j, const Recording& rec, const std::vector<std::size_t>& seq,
                   Drawing& d) {
  const fs::path dir = frames_folder(o);
  d.draw(seq, [&](std::size_t k, const auto& picture) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05zu.png", k);
    write_png((dir / name).string(), picture);
  });
  std::cout << (o.frames_dir.empty() ? std::string("frames") : dir.string()) << ": " << seq.size() << " frames at "
            << o.fps << " fps, t = " << rec.frames[seq.front()].time << " .. " << rec.frames[seq.back()].time << " s"
            << d.colour_note() << "\n";
  const int rc = !o.mp4.empty() && j.mp4_skip.empty() ? encode_mp4(o, dir, seq.size()) : 0;
  std::error_code ec;
  if (o.frames_dir.empty()) fs::remove_all(dir, ec);
  return rc == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"hapticloth-render: offscreen pictures of a cloth run (OSMesa), from an LCM log or live over zenoh"};
  Options o;
  add_options(cli, o);
  if (const int rc = hapticloth::opts::parse(cli, argc, argv); rc >= 0) return rc;
  const std::variant<Job, int> job = check_options(o);
  if (const int* rc = std::get_if<int>(&job)) return *rc;
  const Job& j = std::get<Job>(job);
  const std::variant<Recording, int> read = read_recording(o);
  if (const int* rc = std::get_if<int>(&read)) return *rc;
  const Recording& rec = std::get<Recording>(read);
  const std::vector<std::size_t> seq = j.sequence ? sequence_frames(o, rec) : std::vector<std::size_t>{};
  if (j.sequence && seq.empty()) return 2;
  try {
    Drawing d(o, j, rec);
    if (!o.snapshot.empty()) write_snapshot(o, j, rec, d);
    if (j.sequence && write_sequence(o, j, rec, seq, d) != 0) return 1;
  } catch (const std::exception& e) {
    std::cerr << me << e.what() << "\n";
    return 1;
  }
  if (!j.mp4_skip.empty()) std::cerr << me << j.mp4_skip << "\n";
  return 0;
}
