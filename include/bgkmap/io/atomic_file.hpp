// Outputs are written to a temporary file beside the target and renamed over it only once they
// are complete, so a crash or a full disk never leaves a half-written map behind.
//
// Rules every writer here follows:
// - The temporary is `TARGET.tmp-PID`. Those of a process that no longer runs (a killed build)
//   are removed when the same target is checked again (check_output_path, which every command
//   calls before its work; not on each write, which would list the folder once per file).
// - A target that exists and is not a regular file (a device, a FIFO, a socket) or lies under
//   /dev or /proc (`--report /dev/stdout`) is written through, in place: it is never replaced.
// - A target that is a symbolic link is resolved: the file it names is replaced (or created, for
//   a dangling link), the link stays.
#pragma once

#include <filesystem>
#include <functional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

namespace bgkmap {

// Checks, before any work, that `target` can be written: not a folder, its folder exists and is
// writable (a device or FIFO: itself writable). Throws std::runtime_error naming the path and
// the system's reason (strerror), e.g. "out/m.bgk: cannot write into folder out (No such file
// or directory)". Removes the target's stale temporaries.
void check_output_path(const std::filesystem::path& target);

// The same for an output folder that will be created if missing (e.g. `simulate -o DIR`): the
// folder, or its nearest existing parent, must be a writable folder.
void check_output_folder(const std::filesystem::path& folder);

// A path and what names it in messages ("-o", "--report", "input").
struct NamedPath {
  std::string flag;
  std::filesystem::path path;
};
// Refuses, before any work, outputs that are one file (links and hard links followed), or that
// are one of `inputs`: std::invalid_argument naming both. Targets written in place (devices) are
// not compared.
void check_outputs_apart(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs);

// True for a target written through, in place, rather than replaced: an existing device, FIFO or
// socket, and everything under /dev and /proc.
bool written_in_place(const std::filesystem::path& target);

// Calls write(stream) on a temporary file in the target's folder, flushes, checks the stream and
// renames it to `target`. On any failure the temporary is removed and a std::runtime_error naming
// `target` is thrown; an existing `target` is left untouched.
void write_file_atomically(const std::filesystem::path& target, const std::function<void(std::ostream&)>& write);

// For writers that need a path rather than a stream (e.g. liboctomap, PCL): write(temp_path)
// must create the file at temp_path; it is then renamed to target.
void write_path_atomically(const std::filesystem::path& target,
                           const std::function<void(const std::filesystem::path&)>& write);

// Commits several outputs together. While an OutputBatch exists, the atomic writes of its thread
// leave their finished temporaries pending instead of renaming them; commit() renames them all,
// one after another, once every one is complete. If a write fails, or the batch is destroyed
// without commit(), every pending temporary is removed and every target keeps its old contents.
// What remains: commit() is a series of renames, so a crash in the middle of it (microseconds)
// leaves the targets renamed so far new and the rest old, with their finished temporaries beside
// them. Targets written through (devices, FIFOs) are written when their write happens.
class OutputBatch {
 public:
  OutputBatch();
  ~OutputBatch();
  OutputBatch(const OutputBatch&) = delete;
  OutputBatch& operator=(const OutputBatch&) = delete;

  void commit();

  // Used by the atomic writers: a finished temporary to rename to its target at commit().
  void add(std::filesystem::path temp, std::filesystem::path target);

 private:
  std::vector<std::pair<std::filesystem::path, std::filesystem::path>> pending_;  // temp, target
  OutputBatch* outer_;
};

// The temporaries of `target` (`TARGET.tmp-PID`) whose process no longer runs, removed; returns
// how many.
int remove_stale_temporaries(const std::filesystem::path& target);

}  // namespace bgkmap
