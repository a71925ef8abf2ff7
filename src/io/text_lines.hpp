// Line-by-line reading of text files, plain or gzip-compressed (zlib's gzFile reads both, so a
// .gz file is never unpacked to disk). Shared by the text scan formats (CARMEN logs, ...).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace bgkmap::io_detail {

class TextLines {
 public:
  // Throws InputError naming the file when it cannot be opened.
  explicit TextLines(const std::filesystem::path& file);
  ~TextLines();
  TextLines(const TextLines&) = delete;
  TextLines& operator=(const TextLines&) = delete;

  // The next line, without its end ("\n" or "\r\n"); false after the last. Throws InputError
  // naming the file (and the line) for a truncated or corrupt gzip stream, a read error, binary
  // data (a NUL or other control byte: not a text file, or a gzip file with a damaged header) or
  // a line longer than kMaxLineBytes.
  bool next(std::string& line);

  // 1-based number of the line next() returned last.
  uint64_t line_number() const { return line_number_; }
  const std::filesystem::path& file() const { return file_; }
  // The share of the file the lines returned so far cover, 0 to 1: of its bytes, or of a gzip
  // file's uncompressed size (its trailer's; where that cannot be right, of its compressed bytes,
  // give or take zlib's buffer).
  double fraction_read() const;

  // "line N: what" as an InputError naming the file.
  [[noreturn]] void fail(const std::string& what) const;

  static constexpr size_t kMaxLineBytes = 16u << 20;

 private:
  bool fill();  // reads more bytes into buffer_; false at the end of the data

  std::filesystem::path file_;
  void* gz_ = nullptr;  // gzFile, kept out of this header
  std::string buffer_;
  size_t begin_ = 0;  // start of the unread part of buffer_
  bool at_end_ = false;
  uint64_t file_bytes_ = 0;
  uint64_t text_bytes_ = 0;  // uncompressed, from a gzip trailer; 0 when not known
  uint64_t line_number_ = 0;
};

// At most the first 80 bytes of `text`, control and non-ASCII bytes shown as '?' ("..." after a
// cut): what a one-line error quotes of a bad input (a 30 MB line, terminal escapes).
std::string excerpt(std::string_view text);

// Splits a line at spaces and tabs.
std::vector<std::string_view> split_fields(std::string_view line);

// The whole field as a number; false when it is not one (nan and inf parse, as non-finite).
bool parse_number(std::string_view field, double& value);
// The whole field as a non-negative integer no larger than `max`.
bool parse_count(std::string_view field, uint64_t max, uint64_t& value);

}  // namespace bgkmap::io_detail
