#include "fuzz_support.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include "bgkmap/io/errors.hpp"

namespace bgkmap::fuzz {

std::filesystem::path scratch_path(const char* extension) {
  static const std::filesystem::path dir = std::filesystem::is_directory("/dev/shm") ? "/dev/shm" : "/tmp";
  return dir / ("bgkmap-fuzz-" + std::to_string(::getpid()) + extension);
}

std::filesystem::path write_input(const uint8_t* data, size_t size, const char* extension) {
  const std::filesystem::path file = scratch_path(extension);
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out.flush()) {
    std::fprintf(stderr, "fuzz: cannot write %s\n", file.c_str());
    std::abort();
  }
  return file;
}

void expect_clean(const std::function<void()>& read) {
  try {
    read();
  } catch (const InputError&) {
    // the clean refusal
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz: not an InputError: %s\n", e.what());
    std::abort();
  }
}

}  // namespace bgkmap::fuzz
