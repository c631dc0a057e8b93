#include "app/stop_signal.hpp"

#include <csignal>
#include <cstring>
#include <unistd.h>

namespace hapticloth::app {

namespace {
std::atomic<bool> g_stop{false};
std::atomic<bool> g_winding_down{false};  // false: set-up, a signal exits at once
volatile std::sig_atomic_t g_signal = 0;
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs lock-free flags");

void say(const char* line) {
  const ssize_t ignored = ::write(STDERR_FILENO, line, std::strlen(line));
  (void)ignored;
}

extern "C" void on_stop_signal(int sig) {
  if (g_stop.load(std::memory_order_relaxed)) _exit(128 + sig);
  if (!g_winding_down.load(std::memory_order_relaxed)) {
    say(sig == SIGTERM ? "hapticloth-server: stopped by SIGTERM during set-up (nothing ran)\n"
                       : "hapticloth-server: stopped by SIGINT during set-up (nothing ran)\n");
    _exit(0);
  }
  g_signal = sig;
  g_stop.store(true, std::memory_order_relaxed);
}
}  // namespace

const std::atomic<bool>& install_stop_signals() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  return g_stop;
}

void wind_down_on_stop_signals() { g_winding_down.store(true); }

int stop_signal() { return g_signal; }

}  // namespace hapticloth::app
