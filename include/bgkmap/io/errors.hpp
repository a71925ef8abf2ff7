// The one error type for bad input files: its message is a single line naming the file and what
// is wrong with it ("scan_03.pcd: truncated binary data (expected 56000 bytes, found 1200)").
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

namespace bgkmap {

class InputError : public std::runtime_error {
 public:
  InputError(const std::filesystem::path& file, const std::string& what)
      : std::runtime_error(file.string() + ": " + what), file_(file) {}
  const std::filesystem::path& file() const { return file_; }

 private:
  std::filesystem::path file_;
};

}  // namespace bgkmap
