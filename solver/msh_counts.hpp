// The counts a Gmsh MSH file declares, checked against its size before Gmsh reads it. Gmsh
// reserves memory for the counts a section header declares before it reads the section: a
// 161-byte MSH 4.1 file declaring 1.5e8 nodes made it allocate ~3 GB (and hold the process for
// 13 s). Every declared item takes some bytes of the file, so a count larger than the file could
// hold is refused here, in a single streaming pass that allocates nothing in proportion to the
// file.
#pragma once

#include <cstdint>
#include <string>

namespace softshock {

struct MshCounts {
  double version = 0;   // 2.2, 4.1, ...
  bool binary = false;  // file-type 1
  std::uint64_t file_bytes = 0;
  std::uint64_t nodes = 0;     // the largest count any $Nodes header declares
  std::uint64_t elements = 0;  // likewise for $Elements
};

// Reads the $MeshFormat header and every section header that declares a count ($Nodes,
// $Elements, $Entities, $PhysicalNames, in MSH 2 and 4, ASCII and binary) and checks each count
// against the least number of bytes an item takes in that encoding. Throws std::runtime_error
// saying which section and count break the rule (no path in the message: callers name the file).
MshCounts check_msh_counts(const std::string& path);

}  // namespace softshock
