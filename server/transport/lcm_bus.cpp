#include "transport/lcm_bus.hpp"

#include <filesystem>
#include <stdexcept>

#include <lcm/lcm.h>

namespace hapticloth::transport {

namespace {
void on_message(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  try {
    auto* h = static_cast<std::function<void(const std::uint8_t*, std::size_t)>*>(user);
    (*h)(static_cast<const std::uint8_t*>(rbuf->data), rbuf->data_size);
  } catch (...) {
    // Handlers must not throw; the message is dropped.
  }
}
}  // namespace

std::string lcm_log_url(const std::string& path) {
  return "file://" + std::filesystem::absolute(path).string() + "?mode=w";
}

LcmBus::LcmBus(const std::string& url) : url_(url), lcm_(lcm_create(url.c_str())) {
  if (!lcm_) throw std::runtime_error("lcm: cannot open provider " + url);
}

LcmBus::~LcmBus() {
  stop_.store(true);
  if (rx_.joinable()) rx_.join();
  lcm_destroy(lcm_);
}

bool LcmBus::publish(const std::string& channel, const std::uint8_t* data, std::size_t len) {
  return lcm_publish(lcm_, channel.c_str(), data, static_cast<unsigned>(len)) == 0;
}

void LcmBus::subscribe(const std::string& channel, Handler h) {
  subs_.push_back(std::make_unique<Sub>(Sub{this, std::move(h)}));
  lcm_subscribe(lcm_, channel.c_str(), &on_message, &subs_.back()->h);
}

void LcmBus::start() {
  if (subs_.empty() || rx_.joinable()) return;
  rx_ = std::thread([this] {
    // Bounded waits so the destructor's stop flag is seen within 100 ms.
    while (!stop_.load(std::memory_order_relaxed))
      if (lcm_handle_timeout(lcm_, 100) < 0) break;
  });
}

}  // namespace hapticloth::transport
