// Debian's liboctomap is built with its debug output on: OcTree::writeBinary prints " done." to
// stderr. Writers wrap that call in this guard so the command line stays clean; failures are
// still reported through return values and exceptions. Not thread-safe (it swaps fd 2).
#pragma once

#include <fcntl.h>
#include <unistd.h>

namespace bgkmap {

class QuietStderr {
 public:
  QuietStderr() {
    saved_ = ::dup(2);
    const int null_fd = ::open("/dev/null", O_WRONLY);
    if (saved_ >= 0 && null_fd >= 0) ::dup2(null_fd, 2);
    if (null_fd >= 0) ::close(null_fd);
  }
  ~QuietStderr() {
    if (saved_ >= 0) {
      ::dup2(saved_, 2);
      ::close(saved_);
    }
  }
  QuietStderr(const QuietStderr&) = delete;
  QuietStderr& operator=(const QuietStderr&) = delete;

 private:
  int saved_ = -1;
};

}  // namespace bgkmap
