#include "eval/octree_file.hpp"

#include <octomap/AbstractOcTree.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>
#include <string>

#include "bgkmap/io/errors.hpp"
#include "io/octomap_tree_write.hpp"
#include "io/quiet_stderr.hpp"
#include "io/text_lines.hpp"

namespace bgkmap::eval {

namespace {

constexpr int kTreeDepth = 16;  // OctoMap's: the root at depth 0, the finest leaves at 16

// First lines AbstractOcTree::write and OcTree::writeBinary start with.
const char kTreeFirstLine[] = "# Octomap OcTree file";
const char kBinaryFirstLine[] = "# Octomap OcTree binary file";

struct Header {
  std::string id;
  uint64_t size = 0;
  double resolution = 0;
  size_t data_offset = 0;
  std::optional<TreeValues> values;  // a bgkmap .ot's comment
};

void skip_line(std::istream& in) {
  for (int c = in.get(); in.good() && c != '\n'; c = in.get()) {
  }
}

// Parsed as AbstractOcTree::readHeader does: keyword lines up to "data", '#' lines are comments.
Header read_header(const std::filesystem::path& file, const std::string& bytes, OctreeFile kind) {
  std::istringstream in(bytes);
  std::string line;
  std::getline(in, line);
  const bool binary_header = line.rfind(kBinaryFirstLine, 0) == 0;
  if (kind == OctreeFile::kTree && line.rfind(kTreeFirstLine, 0) != 0)
    throw InputError(file, binary_header ? "is an OctoMap binary tree (.bt content), expected a full tree (.ot)"
                                         : "not an OctoMap tree (the first line is not \"" +
                                               std::string(kTreeFirstLine) + "\")");
  if (kind == OctreeFile::kBinary && !binary_header)
    throw InputError(file, line.rfind(kTreeFirstLine, 0) == 0
                               ? "is a full OctoMap tree (.ot content), expected a binary tree (.bt)"
                               : "not an OctoMap binary tree (the first line is not \"" +
                                     std::string(kBinaryFirstLine) + "\")");
  Header h;
  std::string token;
  bool data = false;
  while (!data && in >> token) {
    if (token == "data") {
      skip_line(in);
      data = true;
    } else if (token == "id") {
      in >> h.id;
    } else if (token == "size") {
      in >> h.size;
    } else if (token == "res") {
      in >> h.resolution;
    } else if (token.rfind('#', 0) == 0) {
      std::string rest;
      std::getline(in, rest);
      if (const std::optional<TreeValues> values = tree_values_in_comment(token + rest)) h.values = values;
    } else {
      skip_line(in);  // a keyword OctoMap does not know either
    }
    if (in.fail()) break;
  }
  if (!data || in.fail()) throw InputError(file, "truncated or corrupt OctoMap header (no id / size / res / data)");
  if (h.id == "1") h.id = "OcTree";  // OctoMap's deprecated id of the OcTree
  if (h.id.empty()) throw InputError(file, "the OctoMap header names no tree type (id)");
  if (!(h.resolution > 0) || !std::isfinite(h.resolution))
    throw InputError(file, "the OctoMap header's resolution is not a positive number");
  if (h.id != "OcTree")
    throw InputError(file, "holds an OctoMap " + io_detail::excerpt(h.id) + ", not an OcTree (bgkmap reads occupancy OcTrees only)");
  if (h.size > 0xFFFFFFFFull) throw InputError(file, "the OctoMap header's node count is out of range");
  h.data_offset = in.eof() ? bytes.size() : static_cast<size_t>(in.tellg());
  return h;
}

struct NodeCursor {
  const unsigned char* p;
  const unsigned char* end;
  uint64_t nodes = 0;
  bool bad_value = false;
};

// .ot node: its float log-odds, then one byte whose bit i says child i follows (depth first).
bool walk_tree_node(NodeCursor& c, int depth) {
  if (c.end - c.p < static_cast<std::ptrdiff_t>(sizeof(float) + 1)) return false;
  float log_odds;
  std::memcpy(&log_odds, c.p, sizeof log_odds);
  if (!std::isfinite(log_odds)) c.bad_value = true;
  const unsigned children = c.p[sizeof(float)];
  c.p += sizeof(float) + 1;
  ++c.nodes;
  if (children != 0 && depth >= kTreeDepth) return false;
  for (int i = 0; i < 8; ++i)
    if ((children >> i) & 1u)
      if (!walk_tree_node(c, depth + 1)) return false;
  return true;
}

// .bt node: two bytes, two bits per child (1 free leaf, 2 occupied leaf, 3 inner: its own two
// bytes follow, depth first, after this node's); the node itself was counted by its parent.
bool walk_binary_node(NodeCursor& c, int depth) {
  if (c.end - c.p < 2) return false;
  const unsigned char bytes[2] = {c.p[0], c.p[1]};
  c.p += 2;
  int inner = 0;
  bool any = false;
  for (int i = 0; i < 8; ++i) {
    const unsigned code = (bytes[i / 4] >> (2 * (i % 4))) & 3u;
    if (code == 0) continue;
    any = true;
    ++c.nodes;
    inner += code == 3;
  }
  if (!any && depth > 0) return false;                   // an inner node without children
  if (inner > 0 && depth + 1 >= kTreeDepth) return false;  // inner nodes below the finest depth
  for (int k = 0; k < inner; ++k)
    if (!walk_binary_node(c, depth + 1)) return false;
  return true;
}

void check_nodes(const std::filesystem::path& file, const std::string& bytes, const Header& h, OctreeFile kind) {
  if (h.size == 0) return;  // OctoMap reads no data then
  NodeCursor c{reinterpret_cast<const unsigned char*>(bytes.data()) + h.data_offset,
               reinterpret_cast<const unsigned char*>(bytes.data()) + bytes.size()};
  bool complete;
  if (kind == OctreeFile::kTree) {
    complete = walk_tree_node(c, 0);
  } else {
    c.nodes = 1;  // the root
    complete = walk_binary_node(c, 0);
  }
  if (!complete) throw InputError(file, "truncated or corrupt OctoMap node data");
  if (c.bad_value) throw InputError(file, "corrupt OctoMap node data (a log-odds value is not finite)");
  if (c.nodes != h.size || c.p != c.end) {
    std::ostringstream msg;
    msg << "corrupt OctoMap file: the header announces " << h.size << " nodes, the data holds " << c.nodes;
    if (c.p != c.end) msg << " followed by " << (c.end - c.p) << " more bytes";
    throw InputError(file, msg.str());
  }
}

}  // namespace

std::unique_ptr<octomap::OcTree> read_octree_file(const std::filesystem::path& file, OctreeFile kind,
                                                  std::optional<TreeValues>* values) {
  if (!std::filesystem::is_regular_file(file)) throw InputError(file, "file not found");
  std::ifstream stream(file, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(stream)), std::istreambuf_iterator<char>());
  if (stream.bad()) throw InputError(file, "could not be read");
  const Header header = read_header(file, bytes, kind);
  check_nodes(file, bytes, header, kind);
  if (values) *values = header.values;

  std::istringstream in(std::move(bytes));
  const QuietStderr quiet;  // liboctomap announces every read on stderr
  if (kind == OctreeFile::kBinary) {
    auto tree = std::make_unique<octomap::OcTree>(header.resolution);
    if (!tree->readBinary(in)) throw InputError(file, "liboctomap could not read this binary tree");
    return tree;
  }
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(in));
  if (!read) throw InputError(file, "liboctomap could not read this tree");
  auto* tree = dynamic_cast<octomap::OcTree*>(read.get());
  if (!tree) throw InputError(file, "holds an OctoMap " + io_detail::excerpt(read->getTreeType()) + ", not an OcTree");
  read.release();
  return std::unique_ptr<octomap::OcTree>(tree);
}

}  // namespace bgkmap::eval
