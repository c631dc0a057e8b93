// The files a session writes (its LCM log, its device record, its MCAP), claimed for the
// session: each is held under an exclusive advisory lock (flock) from before the session
// starts until it ends, so a second server given the same path stops with an error naming it
// instead of truncating a file the first is still writing. The claim does not truncate: the
// writers (LCM's file provider, DeviceLogWriter, the MCAP writer) open the path themselves
// once it is held. A file the claim created is removed again if the session never started
// (a bad option or endpoint found after the claim): a failed start leaves nothing behind.
#pragma once

#include <string>
#include <vector>

namespace hapticloth::app {

class OutputClaims {
 public:
  OutputClaims() = default;
  ~OutputClaims();
  OutputClaims(const OutputClaims&) = delete;
  OutputClaims& operator=(const OutputClaims&) = delete;

  /// Claims `path` (created if missing, left as it is otherwise), written under `what` (the
  /// option or key that named it, for the error). Throws ConfigError "WHAT PATH: ..." when
  /// another process holds it or it cannot be opened for writing. An empty path claims nothing.
  /// Also throws when what is there is not a regular file (/dev/full, a FIFO).
  void claim(const std::string& path, const std::string& what);
  /// The session ran: its files stay (else the destructor removes those the claims created).
  void keep() { created_.clear(); }

 private:
  std::vector<int> fds_;
  std::vector<std::string> created_;
};

}  // namespace hapticloth::app
