#include "app/stop_signal.hpp"

#include <csignal>
#include <string>
#include <unistd.h>

namespace hapticloth::app {

namespace {
std::atomic<bool> g_stop{false};
volatile std::sig_atomic_t g_signal = 0;
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void on_stop_signal(int sig) {
  if (g_stop.load(std::memory_order_relaxed)) _exit(128 + sig);
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

int stop_signal() { return g_signal; }

const char* stop_signal_name() { return g_signal == SIGTERM ? "SIGTERM" : "SIGINT"; }

StoppedDuringSetUp::StoppedDuringSetUp()
    : std::runtime_error(std::string("stopped by ") + stop_signal_name() + " during set-up (nothing ran)") {}

void check_stop(const std::atomic<bool>* stop) {
  if (stop && stop->load()) throw StoppedDuringSetUp();
}

}  // namespace hapticloth::app
