// hapticloth-export: an LCM log of a session (the server's --lcm-log, hapticloth-record) as an
// MCAP file of the Foxglove channels, the same ones `hapticloth-server --mcap` writes
// (transport/foxglove_sink.hpp), each message at its log event's time.
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>

#include <lcm/eventlog.h>

#include "log/input_file.hpp"
#include "cli_checks.hpp"

#include "transport/foxglove_sink.hpp"
#include "transport/topics.hpp"

namespace {

using namespace hapticloth;

// The Hub's LCM channels and their topics (HAPTICLOTH_<TOPIC>).
std::map<std::string, transport::Topic> hub_channels() {
  std::map<std::string, transport::Topic> m;
  for (int t = 0; t < transport::kTopics; ++t) {
    const auto topic = static_cast<transport::Topic>(t);
    m[transport::lcm_channel(transport::topic_name(topic))] = topic;
  }
  return m;
}

struct Counts {
  std::uint64_t events = 0;
  std::map<std::string, std::uint64_t> other;  // channels the export does not carry
  std::string damaged;  // where the log stops making sense (a cut-off or corrupt tail), or ""
};

// Every readable event of the log into the sink. LCM's reader stops at the first event it
// cannot read (a log cut off mid-write, a corrupt length) as it stops at the end: where it
// stopped short of the file's size, the rest is damaged. Throws std::runtime_error naming the
// log when nothing at all can be read.
Counts export_log(const std::string& path, transport::FoxgloveSink& sink) {
  if (std::string e = devices::check_input_file(path, 0); !e.empty()) throw std::runtime_error(e);
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "r");
  if (!log) throw std::runtime_error(path + ": cannot open the LCM log");
  const auto channels = hub_channels();
  Counts c;
  long read_to = 0;  // the end of the last whole event
  while (lcm_eventlog_event_t* e = lcm_eventlog_read_next_event(log)) {
    ++c.events;
    read_to = std::ftell(log->f);
    const auto it = channels.find(std::string(e->channel, e->channellen));
    if (it == channels.end())
      ++c.other[std::string(e->channel, e->channellen)];
    else
      sink.send(it->second, static_cast<const std::uint8_t*>(e->data), e->datalen, e->timestamp);
    lcm_eventlog_free_event(e);
  }
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec && read_to >= 0 && static_cast<std::uintmax_t>(read_to) < size)
    c.damaged = path + ": the log cannot be read past byte " + std::to_string(read_to) + " of " +
                std::to_string(size) + " (cut off or corrupt); exported the " + std::to_string(c.events) +
                " events before it";
  lcm_eventlog_destroy(log);
  if (c.events == 0) throw std::runtime_error(path + ": no LCM events (not an LCM log, or empty)");
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"hapticloth-export: an LCM log of a session as MCAP (the Foxglove channels of hapticloth-server --mcap)"};
  std::string log_path;
  transport::FoxgloveOptions fo;
  cli.add_option("log", log_path, "LCM log (hapticloth-server --lcm-log, hapticloth-record)")
      ->required()
      ->check(CLI::ExistingFile);
  cli.add_option("-o,--output", fo.mcap, "the MCAP file to write (new)")->required()->check(hapticloth::opts::new_file());
  cli.add_option("--finger-radius", fo.finger_radius, "m, the fingertip spheres on /fingertips (default 0.008, the scenes' default)")
      ->check(hapticloth::opts::positive(0.1, "m"));
  if (const int rc = hapticloth::opts::parse(cli, argc, argv); rc >= 0) return rc;
  bool created = false;
  try {
    transport::FoxgloveSink sink(fo);
    created = true;
    const Counts c = export_log(log_path, sink);
    sink.close();
    std::cout << fo.mcap << ":";
    for (int ch = 0; ch < transport::FoxgloveSink::kChannels; ++ch) {
      const auto k = static_cast<transport::FoxgloveSink::Channel>(ch);
      std::cout << (ch ? ", " : " ") << transport::FoxgloveSink::channel_name(k) << " " << sink.written(k);
    }
    std::cout << " messages from " << c.events << " LCM events\n";
    if (sink.undecodable() > 0) std::cout << "skipped          " << sink.undecodable() << " messages that do not decode\n";
    if (sink.before_topology() > 0)
      std::cout << "skipped          " << sink.before_topology() << " cloth states before the log's topology\n";
    for (const auto& [channel, n] : c.other) std::cout << "not exported     " << channel << ": " << n << "\n";
    if (!c.damaged.empty()) {
      std::cerr << "hapticloth-export: " << c.damaged << "\n";
      return 1;
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "hapticloth-export: " << e.what() << "\n";
    std::error_code ec;
    if (created) std::filesystem::remove(fo.mcap, ec);  // no half file left behind (it was new)
    return 1;
  }
}
