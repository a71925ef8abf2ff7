#include "text_lines.hpp"

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>

#include "bgkmap/io/errors.hpp"

namespace bgkmap::io_detail {

namespace {
constexpr unsigned kChunkBytes = 1u << 16;

gzFile as_gz(void* p) { return static_cast<gzFile>(p); }

// Text holds no control bytes but tab, CR and LF (and form feed / vertical tab, harmless).
bool is_binary_byte(unsigned char c) { return c < 0x20 && c != '\t' && c != '\r' && c != '\n' && c != '\f' && c != '\v'; }
}  // namespace

TextLines::TextLines(const std::filesystem::path& file) : file_(file) {
  errno = 0;
  gz_ = gzopen(file.c_str(), "rb");
  if (!gz_) throw InputError(file, std::string("cannot open (") + (errno ? std::strerror(errno) : "out of memory") + ")");
  gzbuffer(as_gz(gz_), kChunkBytes);
  std::error_code ec;
  file_bytes_ = std::filesystem::is_regular_file(file, ec) ? std::filesystem::file_size(file, ec) : 0;
  if (ec) file_bytes_ = 0;
  // A gzip file ends in its uncompressed size modulo 2^32: right for one stream under 4 GiB that
  // is larger than its compressed bytes (text always is).
  if (file_bytes_ <= 18) return;  // a pipe, or no room for a gzip header and trailer
  std::ifstream in(file, std::ios::binary);
  unsigned char size[4] = {};
  if (in.seekg(-4, std::ios::end) && in.read(reinterpret_cast<char*>(size), 4)) {
    const uint64_t trailer = size[0] | size[1] << 8 | size[2] << 16 | uint64_t(size[3]) << 24;
    if (trailer > file_bytes_) text_bytes_ = trailer;
  }
}

TextLines::~TextLines() {
  if (gz_) gzclose_r(as_gz(gz_));
}

double TextLines::fraction_read() const {
  gzFile gz = as_gz(gz_);
  const z_off_t out = gztell(gz);  // uncompressed bytes handed out, some not yet split into lines
  const uint64_t unread = buffer_.size() - begin_;
  const uint64_t text = out > 0 && static_cast<uint64_t>(out) > unread ? static_cast<uint64_t>(out) - unread : 0;
  const uint64_t whole = gzdirect(gz) ? file_bytes_ : text_bytes_;
  if (whole > 0 && text <= whole) return double(text) / double(whole);
  const z_off_t in = gzoffset(gz);
  return file_bytes_ > 0 && in > 0 ? std::min(1.0, double(in) / double(file_bytes_)) : 0.0;
}

void TextLines::fail(const std::string& what) const {
  throw InputError(file_, "line " + std::to_string(line_number_) + ": " + what);
}

bool TextLines::fill() {
  if (at_end_) return false;
  if (begin_ > 0) {
    buffer_.erase(0, begin_);
    begin_ = 0;
  }
  const size_t old = buffer_.size();
  buffer_.resize(old + kChunkBytes);
  const int got = gzread(as_gz(gz_), buffer_.data() + old, kChunkBytes);
  int code = Z_OK;
  const char* message = gzerror(as_gz(gz_), &code);
  if (got < 0 || code != Z_OK) {
    // Z_BUF_ERROR: the compressed stream ended early (a truncated .gz file).
    const std::string what = code == Z_BUF_ERROR ? "truncated gzip stream (unexpected end of file)"
                             : code == Z_ERRNO   ? std::string("read error (") + std::strerror(errno) + ")"
                                                 : std::string("corrupt gzip stream (") + message + ")";
    throw InputError(file_, "after line " + std::to_string(line_number_) + ": " + what);
  }
  buffer_.resize(old + static_cast<size_t>(got));
  if (got == 0) at_end_ = true;
  return got > 0;
}

bool TextLines::next(std::string& line) {
  size_t searched = 0;  // bytes after begin_ already known to hold no line end
  for (;;) {
    const size_t end = buffer_.find('\n', begin_ + searched);
    const bool last_unterminated = end == std::string::npos && at_end_ && begin_ < buffer_.size();
    if (end != std::string::npos || last_unterminated) {
      const size_t stop = end != std::string::npos ? end : buffer_.size();
      line.assign(buffer_, begin_, stop - begin_);
      begin_ = end != std::string::npos ? end + 1 : buffer_.size();
      ++line_number_;
      if (!line.empty() && line.back() == '\r') line.pop_back();
      for (unsigned char c : line)
        if (is_binary_byte(c))
          fail("binary data (byte " + std::to_string(int(c)) + "): not a text file, or a damaged gzip file");
      return true;
    }
    searched = buffer_.size() - begin_;
    if (searched > kMaxLineBytes) {
      ++line_number_;
      fail("line longer than " + std::to_string(kMaxLineBytes) + " bytes");
    }
    if (!fill() && begin_ >= buffer_.size()) return false;
  }
}

std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> fields;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) fields.push_back(line.substr(start, i - start));
  }
  return fields;
}

bool parse_number(std::string_view field, double& value) {
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);  // from_chars takes no '+'
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  return ec == std::errc() && end == field.data() + field.size() && !field.empty();
}

bool parse_count(std::string_view field, uint64_t max, uint64_t& value) {
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  return ec == std::errc() && end == field.data() + field.size() && !field.empty() && value <= max;
}

std::string excerpt(std::string_view text) {
  constexpr size_t kShownBytes = 80;
  std::string out;
  for (size_t i = 0; i < text.size() && i < kShownBytes; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    out += (c >= 0x20 && c < 0x7f) || c == '\t' ? static_cast<char>(c) : '?';
  }
  return text.size() > kShownBytes ? out + "..." : out;
}

}  // namespace bgkmap::io_detail
