// The memory a process that maps may use, and the check made before each step that takes a lot
// of it. The model: resident memory now (/proc/self/statm) plus what the next step will allocate
// must stay within the limit; the step's size is estimated from its inputs (a map pool's next
// growth, a scan's bucketing pairs, a GP block's matrices), so work that would not fit is refused
// before it starts, with a one-line message naming the flags that would make it fit, instead of
// ending in an out-of-memory kill or a std::bad_alloc thrown inside an OpenMP region.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace bgkmap {

// Work that would take the process beyond memory_limit_bytes(); its message is one line.
class MemoryLimitExceeded : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Physical memory (sysconf), 0 if unknown.
uint64_t physical_memory_bytes();
// Resident memory of this process now (/proc/self/statm), 0 if unknown.
uint64_t resident_memory_bytes();

// Half of physical memory, or 3/4 of the address-space limit (ulimit -v, prlimit --as) when that
// is lower (virtual reservations of threads and libraries count there too); 8 GiB if neither is
// known.
uint64_t default_memory_limit_bytes();

// The process-wide limit (the CLI's --max-memory); 0 restores the default. Not thread-safe: set
// it before mapping starts.
void set_memory_limit_bytes(uint64_t bytes);
uint64_t memory_limit_bytes();

// Throws MemoryLimitExceeded unless resident memory plus `more_bytes` fits the limit:
// "WHAT needs 2.1 GB more (0.3 GB in use), beyond --max-memory 1.0 GB: HINT".
void require_memory(double more_bytes, const std::string& what, const std::string& hint);

// The capacity (in elements of `element_bytes`) a growing array should take next to hold at
// least `needed` elements: double `capacity`, or less when doubling would not fit the limit
// (so that a map near the limit still grows by what it needs); throws MemoryLimitExceeded via
// require_memory when not even `needed` fits.
size_t grown_capacity(size_t capacity, size_t needed, size_t element_bytes, const std::string& what,
                      const std::string& hint);

// "50M", "2G", "1.5g", "500k", "123456" (bytes; K, M, G, T are powers of 1024) to bytes; throws
// std::invalid_argument naming the text for anything else.
uint64_t parse_byte_size(const std::string& text);
// 1536 -> "1.5 KiB", 3221225472 -> "3.0 GiB".
std::string format_bytes(double bytes);

}  // namespace bgkmap
