#include "bgkmap/io/atomic_file.hpp"

#include <unistd.h>

#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

namespace bgkmap {

namespace {
std::filesystem::path temp_path_for(const std::filesystem::path& target) {
  // Same folder, so the rename is atomic; pid keeps concurrent writers apart.
  std::filesystem::path tmp = target;
  tmp += ".tmp-" + std::to_string(::getpid());
  return tmp;
}

void commit(const std::filesystem::path& tmp, const std::filesystem::path& target) {
  std::error_code ec;
  std::filesystem::rename(tmp, target, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw std::runtime_error(target.string() + ": cannot move the finished file into place (" + ec.message() + ")");
  }
}
}  // namespace

void write_file_atomically(const std::filesystem::path& target, const std::function<void(std::ostream&)>& write) {
  write_path_atomically(target, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(target.string() + ": cannot open for writing");
    write(out);
    out.flush();
    if (!out) throw std::runtime_error(target.string() + ": write failed (disk full?)");
  });
}

void write_path_atomically(const std::filesystem::path& target,
                           const std::function<void(const std::filesystem::path&)>& write) {
  const std::filesystem::path tmp = temp_path_for(target);
  try {
    write(tmp);
    if (!std::filesystem::exists(tmp)) throw std::runtime_error(target.string() + ": writer produced no file");
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
  commit(tmp, target);
}

}  // namespace bgkmap
