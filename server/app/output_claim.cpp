#include "app/output_claim.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "app/toml_file.hpp"

namespace hapticloth::app {

OutputClaims::~OutputClaims() {
  for (int fd : fds_) ::close(fd);  // releases the locks
}

void OutputClaims::claim(const std::string& path, const std::string& what) {
  if (path.empty()) return;
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0)
    throw ConfigError(what + " " + path + ": cannot write it (" + std::strerror(errno) + ")");
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    ::close(fd);
    if (err == EWOULDBLOCK)
      throw ConfigError(what + " " + path + ": another running session is writing it; give this "
                        "session a path of its own");
    throw ConfigError(what + " " + path + ": cannot lock it (" + std::strerror(err) + ")");
  }
  fds_.push_back(fd);
}

}  // namespace hapticloth::app
