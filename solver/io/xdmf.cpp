// The XDMF 3 companion of result.h5: light XML that points into the HDF5 file, so ParaView
// (and meshio) read the fields without a converter. The document is built as a string here;
// result_writer.cpp writes it durably next to result.h5.
#include <array>
#include <charconv>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

namespace softshock::detail {

namespace {

// Shortest text that reads back as the same double: frame times in the XML must match the
// `time` attributes in the HDF5 file exactly, whatever the reader.
std::string exact_double(double v) {
  std::array<char, 32> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  if (ec != std::errc{}) throw std::runtime_error("XDMF: cannot format a frame time");
  return std::string(buf.data(), end);
}

// One HDF5-backed DataItem. Dimensions are written row-major (slowest first), as XDMF and
// HDF5 both expect; DataType/Precision describe the stored type so no reader converts.
std::string data_item(const std::string& h5_file, const std::string& dataset,
                      const std::string& dims, bool is_int, const std::string& indent) {
  return indent + "<DataItem Dimensions=\"" + dims + "\" DataType=\"" +
         (is_int ? "Int\" Precision=\"4\"" : "Float\" Precision=\"8\"") + " Format=\"HDF\">" +
         h5_file + ":" + dataset + "</DataItem>\n";
}

// Topology and geometry of one grid. Every grid references the same two datasets of /mesh:
// the data are stored once, and the mesh is the reference configuration (displacement gives
// the motion). 2-D: triangles on (x, y) nodes; 3-D: tetrahedra on (x, y, z) nodes.
std::string mesh_elements(const std::string& h5_file, int dimension, std::size_t nodes,
                          std::size_t elements, const std::string& indent) {
  const bool three_d = dimension == 3;
  const std::string e = std::to_string(elements), n = std::to_string(nodes);
  const std::string topology = three_d ? "Tetrahedron" : "Triangle";
  const std::string connectivity = three_d ? "/mesh/tetrahedra" : "/mesh/triangles";
  const std::string per_element = three_d ? " 4" : " 3";
  const std::string geometry = three_d ? "XYZ" : "XY";
  const std::string per_node = three_d ? " 3" : " 2";
  return indent + "<Topology TopologyType=\"" + topology + "\" NumberOfElements=\"" + e + "\">\n" +
         data_item(h5_file, connectivity, e + per_element, true, indent + "  ") + indent +
         "</Topology>\n" + indent + "<Geometry GeometryType=\"" + geometry + "\">\n" +
         data_item(h5_file, "/mesh/nodes", n + per_node, false, indent + "  ") + indent +
         "</Geometry>\n";
}

}  // namespace

// h5_file: the HDF5 file name relative to the XDMF file (readers resolve it against the XDMF
// file's folder, so the pair can be moved together). dimension: the mesh's, 2 or 3.
// frame_groups[k] is the group path of frame k (e.g. "/fields/frame_00000") and frame_times[k]
// its time. attributes: (dataset name, node-centred); node-centred fields are N x 3 vectors (in
// 2-D with z = 0: ParaView's Xdmf3 readers and Warp By Vector need three components), the
// others per-element scalars. node_scalars: datasets of one value per node (the damage), in
// every frame.
std::string xdmf_document(const std::string& h5_file, int dimension, std::size_t nodes,
                          std::size_t elements, const std::vector<std::string>& frame_groups,
                          const std::vector<double>& frame_times,
                          const std::vector<std::pair<std::string, bool>>& attributes,
                          const std::vector<std::string>& node_scalars) {
  if (dimension != 2 && dimension != 3) {
    throw std::invalid_argument("XDMF: dimension " + std::to_string(dimension) + ", not 2 or 3");
  }
  if (frame_groups.size() != frame_times.size()) {
    throw std::invalid_argument("XDMF: frame groups and frame times differ in number");
  }
  std::string x;
  x.reserve(512 + frame_groups.size() * (600 + 200 * attributes.size()));
  x += "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n";
  x += "<Xdmf Version=\"3.0\">\n  <Domain>\n";
  if (frame_groups.empty()) {
    // No frame was written (e.g. a run that failed before t = 0 was output): still describe the
    // reference mesh so the file opens.
    x += "    <Grid Name=\"mesh\" GridType=\"Uniform\">\n";
    x += mesh_elements(h5_file, dimension, nodes, elements, "      ");
    x += "    </Grid>\n";
  } else {
    // One Uniform grid per frame inside one Temporal collection: ParaView animates over the
    // <Time> values, meshio's TimeSeriesReader takes the mesh from the first grid.
    x += "    <Grid Name=\"fields\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    const std::string n = std::to_string(nodes), e = std::to_string(elements);
    for (std::size_t k = 0; k < frame_groups.size(); ++k) {
      const std::string& group = frame_groups[k];
      const std::string name = group.substr(group.find_last_of('/') + 1);
      x += "      <Grid Name=\"" + name + "\" GridType=\"Uniform\">\n";
      x += "        <Time Value=\"" + exact_double(frame_times[k]) + "\"/>\n";
      x += mesh_elements(h5_file, dimension, nodes, elements, "        ");
      for (const auto& [field, nodal] : attributes) {
        x += "        <Attribute Name=\"" + field + "\" AttributeType=\"" +
             (nodal ? "Vector\" Center=\"Node\">\n" : "Scalar\" Center=\"Cell\">\n");
        x += data_item(h5_file, group + "/" + field, nodal ? n + " 3" : e, false, "          ");
        x += "        </Attribute>\n";
      }
      for (const std::string& field : node_scalars) {
        x +=
            "        <Attribute Name=\"" + field + "\" AttributeType=\"Scalar\" Center=\"Node\">\n";
        x += data_item(h5_file, group + "/" + field, n, false, "          ");
        x += "        </Attribute>\n";
      }
      x += "      </Grid>\n";
    }
    x += "    </Grid>\n";
  }
  x += "  </Domain>\n</Xdmf>\n";
  return x;
}

}  // namespace softshock::detail
