#include "app/output_claim.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "app/toml_file.hpp"

namespace hapticloth::app {

OutputClaims::~OutputClaims() {
  for (const std::string& p : created_) ::unlink(p.c_str());  // the session never started
  for (int fd : fds_) ::close(fd);  // releases the locks
}

void OutputClaims::claim(const std::string& path, const std::string& what) {
  if (path.empty()) return;
  int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  const bool created = fd >= 0;
  if (!created && errno == EEXIST) fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0)
    throw ConfigError(what + " " + path + ": cannot write it (" + std::strerror(errno) + ")");
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw ConfigError(what + " " + path + ": not a regular file (a device or FIFO); give a file to write");
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    ::close(fd);
    if (err == EWOULDBLOCK)
      throw ConfigError(what + " " + path + ": another running session is writing it; give this "
                        "session a path of its own");
    throw ConfigError(what + " " + path + ": cannot lock it (" + std::strerror(err) + ")");
  }
  fds_.push_back(fd);
  if (created) created_.push_back(path);
}

}  // namespace hapticloth::app
