#include "solver/msh_counts.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <stdexcept>
#include <string_view>
#include <vector>

namespace softshock {
namespace {

// The least bytes one item takes, per encoding. ASCII: a node is at least "1\n0 0 0\n" (MSH 4)
// or "1 0 0 0\n" (MSH 2), 8 bytes; an element at least a tag and one node, "1 1\n"; an entity or
// a block header at least four one-digit numbers; a physical name at least `1 1 ""`. Binary: a
// node is a tag (int or size_t) and three doubles, an element two ints or two size_ts, a block
// header three ints and a size_t, an entity an int and three doubles.
struct ItemBytes {
  std::uint64_t node, element, block, entity, physical_name;
};
constexpr ItemBytes kAscii{8, 4, 8, 8, 6};
constexpr ItemBytes kBinary{28, 8, 20, 28, 6};

class File {
 public:
  explicit File(const std::string& path) : fd_(::open(path.c_str(), O_RDONLY | O_CLOEXEC)) {
    if (fd_ < 0) throw std::runtime_error(std::string("cannot open: ") + std::strerror(errno));
    const off_t end = ::lseek(fd_, 0, SEEK_END);
    if (end < 0) throw std::runtime_error(std::string("cannot read: ") + std::strerror(errno));
    size_ = static_cast<std::uint64_t>(end);
  }
  ~File() { ::close(fd_); }
  File(const File&) = delete;
  File& operator=(const File&) = delete;
  std::uint64_t size() const { return size_; }
  // Up to n bytes from offset (fewer at the end of the file).
  std::string read(std::uint64_t offset, std::size_t n) const {
    std::string out(n, '\0');
    std::size_t got = 0;
    while (got < n) {
      const ssize_t r = ::pread(fd_, out.data() + got, n - got, static_cast<off_t>(offset + got));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) throw std::runtime_error(std::string("cannot read: ") + std::strerror(errno));
      if (r == 0) break;
      got += static_cast<std::size_t>(r);
    }
    out.resize(got);
    return out;
  }

 private:
  int fd_;
  std::uint64_t size_ = 0;
};

std::string_view first_line(std::string_view s) {
  const std::size_t end = s.find('\n');
  s = s.substr(0, end);
  if (!s.empty() && s.back() == '\r') s.remove_suffix(1);
  return s;
}

// Whitespace-separated unsigned integers of an ASCII header line; false on anything else (a sign,
// a fraction, more digits than 64 bits hold).
bool parse_counts(std::string_view line, std::vector<std::uint64_t>& out) {
  out.clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i == line.size()) break;
    std::uint64_t v = 0;
    const auto [ptr, ec] = std::from_chars(line.data() + i, line.data() + line.size(), v);
    if (ec != std::errc() || ptr == line.data() + i) return false;
    i = static_cast<std::size_t>(ptr - line.data());
    if (i < line.size() && line[i] != ' ' && line[i] != '\t') return false;
    out.push_back(v);
  }
  return true;
}

struct Section {
  std::string_view marker;  // "$Nodes"
  const char* what;         // "nodes"
};

void require_fits(std::uint64_t count, std::uint64_t item_bytes, std::uint64_t file_bytes,
                  const std::string& what, std::string_view section) {
  if (count > file_bytes / item_bytes) {
    throw std::runtime_error(std::string(section) + " declares " + std::to_string(count) + " " +
                             what + ", more than a file of " + std::to_string(file_bytes) +
                             " bytes holds (each takes at least " + std::to_string(item_bytes) +
                             " bytes)");
  }
}

}  // namespace

MshCounts check_msh_counts(const std::string& path) {
  File file(path);
  MshCounts counts;
  counts.file_bytes = file.size();

  // $MeshFormat, then "version file-type data-size".
  const std::string head = file.read(0, 256);
  std::size_t at = head.find_first_not_of(" \t\r\n");
  if (at == std::string::npos || head.compare(at, 11, "$MeshFormat") != 0) {
    throw std::runtime_error("not a Gmsh MSH file (no $MeshFormat header)");
  }
  at = head.find('\n', at);
  if (at == std::string::npos) throw std::runtime_error("the $MeshFormat header is cut short");
  const std::string_view format_line = first_line(std::string_view(head).substr(at + 1));
  {
    double version = 0;
    int file_type = -1, data_size = -1;
    const std::string line(format_line);
    if (std::sscanf(line.c_str(), "%lf %d %d", &version, &file_type, &data_size) != 3 ||
        !(version >= 2.0 && version < 5.0) || (file_type != 0 && file_type != 1) ||
        data_size != 8) {
      throw std::runtime_error(
          "$MeshFormat: expects 'version file-type data-size' with a version "
          "from 2 to 4.x, file-type 0 (ASCII) or 1 (binary) and data-size 8, "
          "got '" +
          line.substr(0, 64) + "'");
    }
    counts.version = version;
    counts.binary = file_type == 1;
  }
  const bool msh4 = counts.version >= 4.0;
  const ItemBytes& item = counts.binary ? kBinary : kAscii;
  const std::uint64_t bytes = counts.file_bytes;

  // Every section header, in one streaming pass: a marker at the start of a line.
  static constexpr Section kSections[] = {{"$Nodes", "nodes"},
                                          {"$Elements", "elements"},
                                          {"$Entities", "entities"},
                                          {"$PhysicalNames", "physical names"}};
  constexpr std::size_t kChunk = 1 << 20, kOverlap = 32;
  std::vector<std::uint64_t> values;
  for (std::uint64_t offset = 0; offset < bytes; offset += kChunk) {
    const std::string chunk = file.read(offset, kChunk + kOverlap);
    for (std::size_t p = chunk.find('$'); p != std::string::npos && p < kChunk;
         p = chunk.find('$', p + 1)) {
      const bool line_start =
          offset + p == 0 || (p > 0 ? chunk[p - 1] == '\n' : file.read(offset - 1, 1) == "\n");
      if (!line_start) continue;
      for (const Section& s : kSections) {
        const std::string_view rest = std::string_view(chunk).substr(p);
        if (rest.substr(0, s.marker.size()) != s.marker) continue;
        std::string_view after = rest.substr(s.marker.size());
        if (!after.empty() && after.front() == '\r') after.remove_prefix(1);
        if (after.empty() || after.front() != '\n') continue;  // "$NodesData" or the like
        const std::uint64_t body = offset + p + (rest.size() - after.size()) + 1;
        const std::string section(s.marker);
        // Counts: one ASCII line, except the binary MSH 4 sections' size_t words
        // ($PhysicalNames is ASCII in every MSH file).
        const bool words = counts.binary && msh4 && s.marker != "$PhysicalNames";
        if (words) {
          const std::size_t n = s.marker == "$Entities" || counts.version >= 4.1 ? 4 : 2;
          const std::string raw = file.read(body, 8 * n);
          if (raw.size() != 8 * n)
            throw std::runtime_error(section + ": the file ends in its header");
          values.assign(n, 0);
          for (std::size_t k = 0; k < n; ++k) std::memcpy(&values[k], raw.data() + 8 * k, 8);
        } else if (!parse_counts(first_line(file.read(body, 256)), values) || values.empty()) {
          throw std::runtime_error(section + ": the header line is not a list of counts");
        }
        if (s.marker == "$Nodes" || s.marker == "$Elements") {
          const bool nodes = s.marker == "$Nodes";
          // MSH 4: blocks, items[, min tag, max tag]; MSH 2: items.
          const std::uint64_t items = msh4 ? (values.size() >= 2 ? values[1] : 0) : values[0];
          if (msh4 && values.size() < 2) {
            throw std::runtime_error(section + ": expects the entity blocks and the " + s.what);
          }
          if (msh4) require_fits(values[0], item.block, bytes, "entity blocks", section);
          require_fits(items, nodes ? item.node : item.element, bytes, s.what, section);
          (nodes ? counts.nodes : counts.elements) =
              std::max(nodes ? counts.nodes : counts.elements, items);
        } else if (s.marker == "$Entities") {
          for (std::uint64_t v : values) require_fits(v, item.entity, bytes, "entities", section);
        } else {
          require_fits(values[0], item.physical_name, bytes, "physical names", section);
        }
      }
    }
  }
  return counts;
}

}  // namespace softshock
