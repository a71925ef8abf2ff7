#include "native_block_codec.hpp"

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace bgkmap::io_detail {

namespace {

// A field's bitmap has one bit per cell; its mask one bit per bitmap byte, set where that byte
// is not zero, and only those bytes are stored (in a 2-D map most of a block's layers are never
// observed, so most bitmap bytes are zero).
size_t bitmap_bytes(size_t cells) { return (cells + 7) / 8; }
size_t mask_bytes(size_t cells) { return (bitmap_bytes(cells) + 7) / 8; }

bool bit(const uint8_t* bits, size_t i) { return (bits[i / 8] >> (i % 8)) & 1u; }

uint32_t bits_of(float v) {
  uint32_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}
float float_of(uint32_t b) {
  float v;
  std::memcpy(&v, &b, sizeof v);
  return v;
}

uint32_t get_u32(const uint8_t* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

float& field(Cell& c, int f) { return f == 0 ? c.alpha : c.beta; }
float field(const Cell& c, int f) { return f == 0 ? c.alpha : c.beta; }
const char* field_name(int f) { return f == 0 ? "alpha" : "beta"; }

void append_field(std::string& out, const Cell* cells, size_t n, int f, uint32_t prior) {
  const size_t mask_at = out.size();
  out.append(mask_bytes(n), '\0');
  size_t moved = 0;
  for (size_t j = 0; j < bitmap_bytes(n); ++j) {
    unsigned byte = 0;
    for (size_t i = 8 * j; i < n && i < 8 * j + 8; ++i) byte |= unsigned(bits_of(field(cells[i], f)) != prior) << (i % 8);
    if (byte == 0) continue;
    out[mask_at + j / 8] = static_cast<char>(out[mask_at + j / 8] | (1u << (j % 8)));
    out.push_back(static_cast<char>(byte));
    moved += static_cast<size_t>(__builtin_popcount(byte));
  }
  const size_t values_at = out.size();
  out.resize(values_at + 4 * moved);
  char* v = out.data() + values_at;
  for (size_t i = 0; i < n; ++i) {
    const uint32_t b = bits_of(field(cells[i], f));
    if (b == prior) continue;
    for (int k = 0; k < 4; ++k) *v++ = static_cast<char>((b >> (8 * k)) & 0xFFu);
  }
}

// Reads one field from [p, end) into `cells`; advances p. "" or what is wrong.
std::string decode_field(const uint8_t*& p, const uint8_t* end, Cell* cells, size_t n, int f, uint32_t prior) {
  const std::string name = field_name(f);
  const size_t masks = mask_bytes(n), bytes = bitmap_bytes(n);
  if (size_t(end - p) < masks) return "it ends inside its " + name + " mask";
  const uint8_t* mask = p;
  p += masks;
  if (bytes % 8 != 0 && (mask[masks - 1] >> (bytes % 8)) != 0) return "its " + name + " mask marks bytes beyond the bitmap";
  std::vector<uint8_t> bitmap(bytes, 0);
  for (size_t j = 0; j < bytes; ++j) {
    if (!bit(mask, j)) continue;
    if (p == end) return "it ends inside its " + name + " bitmap";
    if (*p == 0) return "its " + name + " mask marks a bitmap byte that is 0";
    bitmap[j] = *p++;
  }
  if (n % 8 != 0 && (bitmap[bytes - 1] >> (n % 8)) != 0) return "its " + name + " bitmap marks cells beyond the block";
  for (size_t i = 0; i < n; ++i) {
    if (!bit(bitmap.data(), i)) continue;
    if (size_t(end - p) < 4) return "it ends inside its " + name + " values";
    const uint32_t v = get_u32(p);
    p += 4;
    if (v == prior) return "cell " + std::to_string(i) + "'s " + name + " is marked but is the prior's";
    field(cells[i], f) = float_of(v);
  }
  return "";
}

}  // namespace

size_t min_block_body_bytes(size_t cells_per_block) { return 2 * mask_bytes(cells_per_block); }

size_t max_block_body_bytes(size_t cells_per_block) {
  return 2 * (mask_bytes(cells_per_block) + bitmap_bytes(cells_per_block) + 4 * cells_per_block);
}

size_t append_block_body(std::string& out, const Cell* cells, size_t cells_per_block, const Cell& prior) {
  const size_t at = out.size();
  append_field(out, cells, cells_per_block, 0, bits_of(prior.alpha));
  append_field(out, cells, cells_per_block, 1, bits_of(prior.beta));
  return out.size() - at;
}

std::string decode_block_body(const char* body, size_t n, Cell* cells, size_t cells_per_block, const Cell& prior) {
  for (size_t i = 0; i < cells_per_block; ++i) cells[i] = prior;
  const auto* p = reinterpret_cast<const uint8_t*>(body);
  const uint8_t* end = p + n;
  for (const int f : {0, 1}) {
    const std::string bad = decode_field(p, end, cells, cells_per_block, f, bits_of(f == 0 ? prior.alpha : prior.beta));
    if (!bad.empty()) return bad;
  }
  if (p != end) return std::to_string(end - p) + " bytes follow its cells";
  return "";
}

}  // namespace bgkmap::io_detail
