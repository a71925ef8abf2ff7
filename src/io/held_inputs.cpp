#include "bgkmap/io/held_inputs.hpp"

#include <openssl/evp.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <memory>
#include <vector>

#include "bgkmap/io/errors.hpp"

namespace bgkmap {

namespace {
// Adds a file's bytes to the digest.
void hash_file_into(EVP_MD_CTX* ctx, const std::filesystem::path& file, std::vector<char>& buffer) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, std::string("cannot open for reading (") + std::strerror(errno) + ")");
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    if (in.gcount() > 0) EVP_DigestUpdate(ctx, buffer.data(), static_cast<size_t>(in.gcount()));
  }
  if (in.bad()) throw InputError(file, "read error while hashing");
}
}  // namespace

std::string sha256_of_file(const std::filesystem::path& file) {
  const std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
  if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1)
    throw std::runtime_error("SHA-256 is not available from OpenSSL");
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
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(ctx.get(), digest, &length);
  static const char kHex[] = "0123456789abcdef";
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) {
    hex.push_back(kHex[digest[i] >> 4]);
    hex.push_back(kHex[digest[i] & 0xF]);
  }
  return hex;
}

std::vector<uint64_t> HeldInputs::match(const std::vector<std::filesystem::path>& files) {
  hashes_.assign(files.size(), "");
  record_of_.assign(files.size(), -1);
  std::vector<bool> taken(records_.size(), false);
  std::vector<uint64_t> held(files.size(), 0);
  for (size_t f = 0; f < files.size(); ++f) {
    hashes_[f] = sha256_of_file(files[f]);
    for (size_t r = 0; r < records_.size(); ++r) {
      if (taken[r] || records_[r].sha256 != hashes_[f]) continue;
      taken[r] = true;
      record_of_[f] = static_cast<int64_t>(r);
      held[f] = records_[r].scans;
      break;
    }
  }
  return held;
}

void HeldInputs::add(const std::vector<std::filesystem::path>& files, size_t file, uint64_t scan) {
  if (hashes_.size() != files.size()) {
    hashes_.resize(files.size());
    record_of_.resize(files.size(), -1);
  }
  if (record_of_[file] < 0) {
    if (hashes_[file].empty()) hashes_[file] = sha256_of_file(files[file]);
    record_of_[file] = static_cast<int64_t>(records_.size());
    records_.push_back({files[file].string(), hashes_[file], 0});
  }
  HeldInput& record = records_[static_cast<size_t>(record_of_[file])];
  record.path = files[file].string();
  record.scans = scan + 1;
}

uint64_t HeldInputs::scans() const {
  uint64_t n = 0;
  for (const HeldInput& r : records_) n += r.scans;
  return n;
}

}  // namespace bgkmap
