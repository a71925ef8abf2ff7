// Outputs are written to a temporary file beside the target and renamed over it only once they
// are complete, so a crash or a full disk never leaves a half-written map behind.
#pragma once

#include <filesystem>
#include <functional>
#include <ostream>

namespace bgkmap {

// Calls write(stream) on a temporary file in the target's folder, flushes, checks the stream and
// renames it to `target`. On any failure the temporary is removed and a std::runtime_error naming
// `target` is thrown; an existing `target` is left untouched.
void write_file_atomically(const std::filesystem::path& target, const std::function<void(std::ostream&)>& write);

// For writers that need a path rather than a stream (e.g. liboctomap, PCL): write(temp_path)
// must create the file at temp_path; it is then renamed to target.
void write_path_atomically(const std::filesystem::path& target,
                           const std::function<void(const std::filesystem::path&)>& write);

}  // namespace bgkmap
