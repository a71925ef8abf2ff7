// Which scans a map already holds, so that a build killed part way can be resumed without adding
// any scan twice: per input file its path, the SHA-256 of its bytes and how many of its scans
// are in the map. Stored in the native .bgk header (format version 2).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace bgkmap {

struct HeldInput {
  std::string path;    // as given to the build that read it
  std::string sha256;  // sha256_of_file: of a file, what sha256sum prints
  uint64_t scans = 0;  // 1 for a .pcd; for a .graph its first `scans` nodes, in file order
  // The file's size when hashed (0: a folder, or a map written before sizes were kept): a file
  // that has grown since (a log still being recorded) is recognised by the hash of this prefix.
  uint64_t bytes = 0;

  bool operator==(const HeldInput& o) const {
    return path == o.path && sha256 == o.sha256 && scans == o.scans && bytes == o.bytes;
  }
};

// SHA-256 of a file's bytes as 64 lowercase hex digits (of a folder input, a KITTI sequence: of
// each file's relative path and bytes, in path order); throws InputError naming the file when it
// cannot be read.
std::string sha256_of_file(const std::filesystem::path& file);

// As a .bgk header and a shard manifest store them: [{"path", "sha256", "scans"[, "bytes"]}, ...].
nlohmann::json held_inputs_to_json(const std::vector<HeldInput>& held);
// The records of `inputs`; InputError naming `file` and `what` ("corrupt .bgk header") for a
// record that is not one.
std::vector<HeldInput> held_inputs_from_json(const std::filesystem::path& file, const nlohmann::json& inputs,
                                             const std::string& what);

// The held inputs of a map being built: those stored in a resumed map, then every scan inserted.
class HeldInputs {
 public:
  HeldInputs() = default;
  explicit HeldInputs(std::vector<HeldInput> stored) : records_(std::move(stored)) {}

  // Hashes each input file and matches it to a stored record with the same content, or whose
  // content is the file's first `bytes` bytes (a log that has grown: its held scans are its first
  // ones); each record to one file at most, in order. Returns how many of each file's first scans
  // the map already holds (0 for a file it does not hold). A file of the same path as a record
  // holding several of its scans that matches neither way has changed: InputError naming it
  // (its held scans cannot be told apart, and adding it would count them twice).
  std::vector<uint64_t> match(const std::vector<std::filesystem::path>& files);

  // Scan `scan` (0-based, in file order) of input file `file` is now in the map. Files not seen
  // by match() are hashed here, the first time.
  void add(const std::vector<std::filesystem::path>& files, size_t file, uint64_t scan);

  const std::vector<HeldInput>& records() const { return records_; }
  uint64_t scans() const;

 private:
  std::vector<HeldInput> records_;
  std::vector<std::string> hashes_;   // per input file, once computed
  std::vector<uint64_t> sizes_;       // per input file, with its hash
  std::vector<int64_t> record_of_;    // per input file: its record, or -1
};

}  // namespace bgkmap
