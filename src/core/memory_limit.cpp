#include "bgkmap/core/memory_limit.hpp"

#include <sys/resource.h>
#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>

namespace bgkmap {

namespace {
uint64_t g_limit_bytes = 0;  // 0: the default

// Resident memory for the check of a step of `more_bytes`. What an earlier step freed (a scan's
// bucketing, bhm's or a GP block's work arrays) stays resident in the allocator's free lists and
// would be counted twice, once as in use and once in the next step's estimate: before a step is
// refused, that free memory is handed back to the system and the process measured again.
double resident_for(double more_bytes, double limit) {
  double in_use = double(resident_memory_bytes());
#if defined(__GLIBC__)
  if (in_use + more_bytes > limit) {
    malloc_trim(0);
    in_use = double(resident_memory_bytes());
  }
#endif
  return in_use;
}
}  // namespace

uint64_t physical_memory_bytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  return pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
}

uint64_t resident_memory_bytes() {
  std::ifstream statm("/proc/self/statm");
  uint64_t size_pages = 0, resident_pages = 0;
  if (!(statm >> size_pages >> resident_pages)) return 0;
  return resident_pages * uint64_t(sysconf(_SC_PAGESIZE));
}

uint64_t default_memory_limit_bytes() {
  uint64_t limit = physical_memory_bytes() / 2;
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    const uint64_t of_address_space = uint64_t(as.rlim_cur) / 4 * 3;
    limit = limit > 0 ? std::min(limit, of_address_space) : of_address_space;
  }
  return limit > 0 ? limit : uint64_t(8) << 30;
}

void set_memory_limit_bytes(uint64_t bytes) { g_limit_bytes = bytes; }

uint64_t memory_limit_bytes() { return g_limit_bytes > 0 ? g_limit_bytes : default_memory_limit_bytes(); }

namespace {
// One measurement decides: a second one could differ by the pages touched in between.
void require_fits(double more_bytes, double in_use, double limit, const std::string& what, const std::string& hint) {
  if (in_use + more_bytes <= limit) return;
  throw MemoryLimitExceeded(what + " needs " + format_bytes(more_bytes) + " more (" + format_bytes(in_use) +
                            " in use), beyond --max-memory " + format_bytes(limit) + ": " + hint);
}
}  // namespace

void require_memory(double more_bytes, const std::string& what, const std::string& hint) {
  const double limit = double(memory_limit_bytes());
  require_fits(more_bytes, resident_for(more_bytes, limit), limit, what, hint);
}

size_t grown_capacity(size_t capacity, size_t needed, size_t element_bytes, const std::string& what,
                      const std::string& hint) {
  if (needed <= capacity) return capacity;
  const double limit = double(memory_limit_bytes());
  size_t wanted = std::max(needed, 2 * capacity);
  const double in_use = resident_for(double(wanted - capacity) * double(element_bytes), limit);
  const double room = limit > in_use ? (limit - in_use) / double(element_bytes) : 0;  // elements that still fit
  if (double(wanted - capacity) > room) wanted = std::max(needed, capacity + static_cast<size_t>(room));
  require_fits(double(wanted - capacity) * double(element_bytes), in_use, limit, what, hint);
  return wanted;
}

uint64_t parse_byte_size(const std::string& text) {
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  std::string unit = text.substr(used);
  if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b') && unit.size() > 1) unit.pop_back();  // "50MB"
  if (unit.size() == 2 && (unit[1] == 'i' || unit[1] == 'I')) unit.pop_back();                           // "50Mi"
  double scale = 0;
  if (unit.empty()) {
    scale = 1;
  } else if (unit.size() == 1) {
    switch (std::toupper(static_cast<unsigned char>(unit[0]))) {
      case 'K': scale = 1024.0; break;
      case 'M': scale = 1024.0 * 1024; break;
      case 'G': scale = 1024.0 * 1024 * 1024; break;
      case 'T': scale = 1024.0 * 1024 * 1024 * 1024; break;
      default: break;
    }
  }
  const double bytes = value * scale;
  if (used == 0 || scale == 0 || !std::isfinite(bytes) || bytes < 1 || bytes > 1e18)
    throw std::invalid_argument("'" + text + "' is not a memory size (e.g. 512M, 4G, or bytes)");
  return static_cast<uint64_t>(bytes);
}

std::string format_bytes(double bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (bytes >= 1024 && u < 4) bytes /= 1024, ++u;
  char text[32];
  std::snprintf(text, sizeof text, u == 0 ? "%.0f %s" : "%.1f %s", bytes, units[u]);
  return text;
}

}  // namespace bgkmap
