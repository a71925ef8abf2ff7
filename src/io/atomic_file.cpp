#include "bgkmap/io/atomic_file.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>

namespace bgkmap {

namespace fs = std::filesystem;

namespace {

thread_local OutputBatch* current_batch = nullptr;

const char kTempInfix[] = ".tmp-";

std::string reason(int err) { return std::strerror(err); }

bool under_system_folder(const fs::path& path) {
  const std::string s = fs::absolute(path).lexically_normal().string();
  return s.rfind("/dev/", 0) == 0 || s.rfind("/proc/", 0) == 0;
}

// A symbolic link's file is replaced, not the link.
fs::path folder_of(const fs::path& file) {
  const fs::path parent = file.parent_path();
  return parent.empty() ? fs::path(".") : parent;
}

// The file a chain of symbolic links names, followed link by link so that a dangling link's
// target is found too (weakly_canonical stops at it, and the rename would replace the link).
fs::path resolved(const fs::path& target) {
  constexpr int kMaxLinks = 40;  // as the kernel's ELOOP limit
  fs::path path = target;
  std::error_code ec;
  for (int links = 0; links < kMaxLinks && fs::is_symlink(fs::symlink_status(path, ec)); ++links) {
    const fs::path next = fs::read_symlink(path, ec);
    if (ec) return path;
    path = next.is_absolute() ? next : folder_of(path) / next;
  }
  return path;
}

// One name for a file whether or not it exists yet: its folder resolved, links followed.
fs::path identity(const fs::path& file) {
  std::error_code ec;
  const fs::path real = fs::weakly_canonical(fs::absolute(resolved(file), ec), ec);
  return ec ? fs::absolute(file, ec).lexically_normal() : real;
}

fs::path temp_path_for(const fs::path& target) {
  // Same folder, so the rename is atomic; pid keeps concurrent writers apart.
  fs::path tmp = target;
  tmp += kTempInfix + std::to_string(::getpid());
  return tmp;
}

void move_into_place(const fs::path& tmp, const fs::path& target) {
  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw std::runtime_error(target.string() + ": cannot move the finished file into place (" + ec.message() + ")");
  }
}

void check_writable_folder(const fs::path& folder, const fs::path& named) {
  struct stat st {};
  if (::stat(folder.c_str(), &st) != 0)
    throw std::runtime_error(named.string() + ": cannot write into folder " + folder.string() + " (" + reason(errno) + ")");
  if (!S_ISDIR(st.st_mode))
    throw std::runtime_error(named.string() + ": cannot write into folder " + folder.string() + " (" + reason(ENOTDIR) +
                             ")");
  if (::access(folder.c_str(), W_OK | X_OK) != 0)
    throw std::runtime_error(named.string() + ": cannot write into folder " + folder.string() + " (" + reason(errno) + ")");
}

}  // namespace

// Replacing a device or FIFO with a regular file would break it (as root, `--report /dev/stdout`
// replaced the link).
bool written_in_place(const fs::path& target) {
  if (under_system_folder(target)) return true;
  struct stat st {};
  return ::stat(target.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
}

int remove_stale_temporaries(const fs::path& target) {
  const fs::path file = resolved(target);
  const std::string prefix = file.filename().string() + kTempInfix;
  int removed = 0;
  std::error_code ec;
  for (fs::directory_iterator it(folder_of(file), ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string digits = name.substr(prefix.size());
    if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const pid_t pid = static_cast<pid_t>(std::stol(digits));
    // ESRCH: no such process. A live process (EPERM included) may still be writing it.
    if (pid == ::getpid() || pid <= 0 || ::kill(pid, 0) == 0 || errno != ESRCH) continue;
    std::error_code remove_ec;
    if (fs::remove(it->path(), remove_ec)) ++removed;
  }
  return removed;
}

void check_output_path(const fs::path& target) {
  if (target.empty()) throw std::runtime_error("an output path is empty");
  struct stat st {};
  if (::stat(target.c_str(), &st) == 0) {
    if (S_ISDIR(st.st_mode)) throw std::runtime_error(target.string() + ": is a folder, not a file");
    if (written_in_place(target)) {
      if (::access(target.c_str(), W_OK) != 0)
        throw std::runtime_error(target.string() + ": cannot write (" + reason(errno) + ")");
      return;
    }
  } else if (errno != ENOENT) {
    throw std::runtime_error(target.string() + ": cannot write (" + reason(errno) + ")");
  }
  const fs::path file = resolved(target);
  check_writable_folder(folder_of(file), target);
  remove_stale_temporaries(file);
}

void check_output_folder(const fs::path& folder) {
  std::error_code ec;
  fs::path existing = fs::absolute(folder, ec).lexically_normal();
  if (!existing.has_filename()) existing = existing.parent_path();  // "out/" names "out"
  while (!fs::exists(fs::symlink_status(existing, ec)) && existing.has_relative_path())
    existing = existing.parent_path();
  check_writable_folder(existing, folder);
}

void check_outputs_apart(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs) {
  const auto same = [](const fs::path& a, const fs::path& b) {
    std::error_code ec;
    return identity(a) == identity(b) || fs::equivalent(a, b, ec);
  };
  for (size_t i = 0; i < outputs.size(); ++i) {
    if (written_in_place(outputs[i].path)) continue;
    for (size_t j = 0; j < i; ++j)
      if (same(outputs[i].path, outputs[j].path))
        throw std::invalid_argument(outputs[i].flag + " " + outputs[i].path.string() + " is the same file as " +
                                    outputs[j].flag + " " + outputs[j].path.string() + ": give each output its own path");
    for (const NamedPath& input : inputs)
      if (same(outputs[i].path, input.path))
        throw std::invalid_argument(outputs[i].flag + " " + outputs[i].path.string() + " would overwrite the " +
                                    input.flag + " " + input.path.string() + ": write it elsewhere");
  }
}

void write_file_atomically(const fs::path& target, const std::function<void(std::ostream&)>& write) {
  write_path_atomically(target, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error(target.string() + ": cannot open for writing (" + reason(errno) + ")");
    write(out);
    out.flush();
    if (!out) throw std::runtime_error(target.string() + ": write failed (disk full?)");
  });
}

void write_path_atomically(const fs::path& target, const std::function<void(const fs::path&)>& write) {
  if (written_in_place(target)) {
    write(target);
    return;
  }
  const fs::path file = resolved(target);
  const fs::path tmp = temp_path_for(file);
  try {
    write(tmp);
    if (!fs::exists(tmp)) throw std::runtime_error(target.string() + ": writer produced no file");
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
  if (current_batch) {
    current_batch->add(tmp, file);
    return;
  }
  move_into_place(tmp, file);
}

OutputBatch::OutputBatch() : outer_(current_batch) { current_batch = this; }

OutputBatch::~OutputBatch() {
  current_batch = outer_;
  std::error_code ec;
  for (const auto& [tmp, target] : pending_) fs::remove(tmp, ec);
}

void OutputBatch::add(fs::path temp, fs::path target) {
  for (auto& [tmp, existing] : pending_) {
    if (existing == target) {  // written twice in one batch: the later contents win
      if (tmp != temp) {
        std::error_code ec;
        fs::remove(tmp, ec);
        tmp = std::move(temp);
      }
      return;
    }
  }
  pending_.emplace_back(std::move(temp), std::move(target));
}

void OutputBatch::commit() {
  if (current_batch == this) current_batch = outer_;
  // On a failed rename, move_into_place removes that temporary; the destructor removes the others.
  while (!pending_.empty()) {
    const auto [tmp, target] = pending_.front();
    pending_.erase(pending_.begin());
    move_into_place(tmp, target);
  }
}

}  // namespace bgkmap
