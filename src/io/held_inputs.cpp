#include "bgkmap/io/held_inputs.hpp"

#include <openssl/evp.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>
#include <vector>

#include "bgkmap/io/errors.hpp"

namespace bgkmap {

namespace {
// Adds a file's first `limit` bytes (all of them by default) to the digest.
void hash_file_into(EVP_MD_CTX* ctx, const std::filesystem::path& file, std::vector<char>& buffer,
                    uint64_t limit = UINT64_MAX) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, std::string("cannot open for reading (") + std::strerror(errno) + ")");
  while (in && limit > 0) {
    in.read(buffer.data(), static_cast<std::streamsize>(std::min<uint64_t>(buffer.size(), limit)));
    if (in.gcount() > 0) EVP_DigestUpdate(ctx, buffer.data(), static_cast<size_t>(in.gcount()));
    limit -= static_cast<uint64_t>(in.gcount());
  }
  if (in.bad()) throw InputError(file, "read error while hashing");
}

std::string hex_digest(EVP_MD_CTX* ctx) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(ctx, digest, &length);
  static const char kHex[] = "0123456789abcdef";
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) {
    hex.push_back(kHex[digest[i] >> 4]);
    hex.push_back(kHex[digest[i] & 0xF]);
  }
  return hex;
}

using DigestContext = std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)>;
DigestContext sha256_context() {
  DigestContext ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
  if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1)
    throw std::runtime_error("SHA-256 is not available from OpenSSL");
  return ctx;
}

// SHA-256 of a file's first `bytes` bytes.
std::string sha256_of_prefix(const std::filesystem::path& file, uint64_t bytes) {
  const DigestContext ctx = sha256_context();
  std::vector<char> buffer(1 << 20);
  hash_file_into(ctx.get(), file, buffer, bytes);
  return hex_digest(ctx.get());
}

// A regular file's size, 0 for a folder input (its hash covers several files).
uint64_t size_of_input(const std::filesystem::path& file) {
  std::error_code ec;
  const uint64_t size = std::filesystem::is_regular_file(file, ec) ? std::filesystem::file_size(file, ec) : 0;
  return ec ? 0 : size;
}
}  // namespace

std::string sha256_of_file(const std::filesystem::path& file) {
  const DigestContext ctx = sha256_context();
  std::vector<char> buffer(1 << 20);
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) {
    // A folder input (a KITTI sequence): every regular file in it, by relative path, each path
    // hashed before its bytes.
    std::vector<std::filesystem::path> files;
    for (std::filesystem::recursive_directory_iterator it(file, ec), end; !ec && it != end; it.increment(ec))
      if (it->is_regular_file()) files.push_back(it->path());
    if (ec) throw InputError(file, "cannot list folder (" + ec.message() + ")");
    std::sort(files.begin(), files.end());
    for (const std::filesystem::path& f : files) {
      const std::string name = std::filesystem::relative(f, file).generic_string();
      EVP_DigestUpdate(ctx.get(), name.c_str(), name.size() + 1);
      hash_file_into(ctx.get(), f, buffer);
    }
  } else {
    hash_file_into(ctx.get(), file, buffer);
  }
  return hex_digest(ctx.get());
}

std::vector<uint64_t> HeldInputs::match(const std::vector<std::filesystem::path>& files) {
  hashes_.assign(files.size(), "");
  sizes_.assign(files.size(), 0);
  record_of_.assign(files.size(), -1);
  std::vector<bool> taken(records_.size(), false);
  std::vector<uint64_t> held(files.size(), 0);
  const auto take = [&](size_t f, size_t r) {
    taken[r] = true;
    record_of_[f] = static_cast<int64_t>(r);
    held[f] = records_[r].scans;
  };
  for (size_t f = 0; f < files.size(); ++f) {
    hashes_[f] = sha256_of_file(files[f]);
    sizes_[f] = size_of_input(files[f]);
    for (size_t r = 0; r < records_.size() && record_of_[f] < 0; ++r)
      if (!taken[r] && records_[r].sha256 == hashes_[f]) take(f, r);
  }
  // Files that have grown since: a record's whole content is their beginning.
  for (size_t f = 0; f < files.size(); ++f)
    for (size_t r = 0; r < records_.size() && record_of_[f] < 0; ++r) {
      const HeldInput& record = records_[r];
      if (!taken[r] && record.bytes > 0 && record.bytes < sizes_[f] && sha256_of_prefix(files[f], record.bytes) == record.sha256)
        take(f, r);
    }
  for (size_t f = 0; f < files.size(); ++f)
    for (size_t r = 0; r < records_.size() && record_of_[f] < 0; ++r)
      if (!taken[r] && records_[r].scans > 1 && records_[r].path == files[f].string())
        throw InputError(files[f], "changed since the resumed map read " + std::to_string(records_[r].scans) +
                                       " of its scans (neither the same content nor a longer file beginning with " +
                                       "it): give the file it read, or build afresh");
  return held;
}

void HeldInputs::add(const std::vector<std::filesystem::path>& files, size_t file, uint64_t scan) {
  if (hashes_.size() != files.size()) {
    hashes_.resize(files.size());
    sizes_.resize(files.size());
    record_of_.resize(files.size(), -1);
  }
  if (hashes_[file].empty()) {
    hashes_[file] = sha256_of_file(files[file]);
    sizes_.resize(files.size());
    sizes_[file] = size_of_input(files[file]);
  }
  if (record_of_[file] < 0) {
    record_of_[file] = static_cast<int64_t>(records_.size());
    records_.push_back({files[file].string(), hashes_[file], 0, sizes_[file]});
  }
  HeldInput& record = records_[static_cast<size_t>(record_of_[file])];
  record.path = files[file].string();
  record.sha256 = hashes_[file];  // a grown file: the record now names what it grew to
  record.bytes = sizes_[file];
  record.scans = scan + 1;
}

nlohmann::json held_inputs_to_json(const std::vector<HeldInput>& held) {
  nlohmann::json inputs = nlohmann::json::array();
  for (const HeldInput& h : held) {
    nlohmann::json record{{"path", h.path}, {"sha256", h.sha256}, {"scans", h.scans}};
    if (h.bytes > 0) record["bytes"] = h.bytes;
    inputs.push_back(std::move(record));
  }
  return inputs;
}

std::vector<HeldInput> held_inputs_from_json(const std::filesystem::path& file, const nlohmann::json& inputs,
                                             const std::string& what) {
  if (!inputs.is_array()) throw InputError(file, what + " (no \"inputs\" list)");
  const auto is_sha256_hex = [](const std::string& s) {
    return s.size() == 64 && s.find_first_not_of("0123456789abcdef") == std::string::npos;
  };
  std::vector<HeldInput> held;
  for (const nlohmann::json& r : inputs) {
    const std::string where = what + " (held input " + std::to_string(held.size()) + ": ";
    if (!r.is_object() || !r.contains("path") || !r["path"].is_string() || !r.contains("sha256") ||
        !r["sha256"].is_string() || !r.contains("scans") || !r["scans"].is_number_unsigned())
      throw InputError(file, where + "expected {\"path\", \"sha256\", \"scans\"})");
    HeldInput h{r["path"].get<std::string>(), r["sha256"].get<std::string>(), r["scans"].get<uint64_t>()};
    if (r.contains("bytes")) {
      if (!r["bytes"].is_number_unsigned()) throw InputError(file, where + "\"bytes\" is not a size)");
      h.bytes = r["bytes"].get<uint64_t>();
    }
    if (!is_sha256_hex(h.sha256)) throw InputError(file, where + "sha256 is not 64 lowercase hex digits)");
    if (h.scans == 0) throw InputError(file, where + "holds 0 scans)");
    held.push_back(std::move(h));
  }
  return held;
}

uint64_t HeldInputs::scans() const {
  uint64_t n = 0;
  for (const HeldInput& r : records_) n += r.scans;
  return n;
}

}  // namespace bgkmap
