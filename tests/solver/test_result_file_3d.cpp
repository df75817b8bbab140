// 3-D result files (tetrahedra), beyond the round trip in test_result_file.cpp: the whole HDF5
// layout (docs/results-format.md), the XDMF companion's topology and geometry, the writer's
// refusals and the reader's checks of a stored mesh. Part of the test_result_file binary.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "result_file_helpers.hpp"
#include "scratch_dir.hpp"
#include "solver/io/result_file.hpp"
#include "tet_box.hpp"

namespace softshock {
namespace {

// ScratchDir(prefix): tests/solver/scratch_dir.hpp.
class ScratchDir : public testing::ScratchDir {
 public:
  ScratchDir() : testing::ScratchDir("result3d") {}
};

using namespace testing;  // softshock::testing: the helpers

// The hand-built box the 3-D tests use (tet_box.hpp): positive tetrahedra filling the box, and
// boundary faces that close it, outward: by the divergence theorem the faces' area vectors sum
// to 0 and the flux of (x, 0, 0) through them is the volume.
TEST(ResultFile3d, TheTestBoxIsPositiveAndClosedByOutwardFaces) {
  const Mesh m = tet_box(2.0, 1.0, 0.5, 4, 2, 3);
  EXPECT_EQ(m.node_count(), 5u * 3u * 4u);
  EXPECT_EQ(m.element_count(), 6u * 4u * 2u * 3u);
  EXPECT_EQ(m.boundary_faces.size(), 4u * (4 * 2 + 4 * 3 + 2 * 3));
  double volume = 0;
  for (const auto& t : m.tetrahedra) {
    const double six_v = tet_triple_product(m, t[0], t[1], t[2], t[3]);
    EXPECT_GT(six_v, 0);
    volume += six_v / 6;
  }
  EXPECT_NEAR(volume, 1.0, 1e-12);
  double flux = 0, area[3] = {0, 0, 0};
  for (const auto& f : m.boundary_faces) {
    const double ux = m.x[f[1]] - m.x[f[0]], uy = m.y[f[1]] - m.y[f[0]], uz = m.z[f[1]] - m.z[f[0]];
    const double vx = m.x[f[2]] - m.x[f[0]], vy = m.y[f[2]] - m.y[f[0]], vz = m.z[f[2]] - m.z[f[0]];
    const double n[3] = {0.5 * (uy * vz - uz * vy), 0.5 * (uz * vx - ux * vz),
                         0.5 * (ux * vy - uy * vx)};
    for (int i = 0; i < 3; ++i) area[i] += n[i];
    flux += n[0] * (m.x[f[0]] + m.x[f[1]] + m.x[f[2]]) / 3;
  }
  for (double a : area) EXPECT_NEAR(a, 0.0, 1e-12);
  EXPECT_NEAR(flux, 1.0, 1e-12);
}

TEST(ResultFile3d, LayoutMatchesTheDocumentedContract) {
  ScratchDir dir;
  // 6 x 6 x 5 cubes: 294 nodes, 1080 tetrahedra (17.3 KB: chunked), 384 boundary faces (4.6 KB:
  // contiguous).
  const Mesh mesh = tet_box(1.0, 1.0, 0.5, 6, 6, 5);
  const std::size_t n = mesh.node_count(), e = mesh.element_count();
  const std::size_t faces = mesh.boundary_faces.size();
  ASSERT_EQ(e, 1080u);
  ASSERT_EQ(faces, 384u);
  write_result(dir.str(), mesh, {0.0, 1e-6}, make_history(9, 4));
  H5File f(dir.str("result.h5"));
  ASSERT_GE(f.id, 0);

  EXPECT_EQ(sorted_objects(f.id),
            expected_layout(n, e, 2, 9, 4,
                            {"boundary_faces int32 [" + std::to_string(faces) + " x 3]",
                             "nodes float64 [" + std::to_string(n) + " x 3]",
                             "tetrahedra int32 [" + std::to_string(e) + " x 4]"}));
  EXPECT_EQ(attribute_names(f.id), kRootAttributes);
  EXPECT_EQ(attr_type(f.id, "dimension"), std::make_pair(H5T_INTEGER, std::size_t{4}));
  EXPECT_EQ(int_attr(f.id, "dimension"), 3);
  EXPECT_EQ(int_attr(f.id, "format_version"), 2);

  const auto nodes = shape_of(f.id, "/mesh/nodes");
  EXPECT_EQ(nodes.units, "m");
  EXPECT_EQ(nodes.layout, H5D_CONTIGUOUS);
  const auto tets = shape_of(f.id, "/mesh/tetrahedra");
  ASSERT_EQ(tets.layout, H5D_CHUNKED);  // connectivity: shuffle + deflate, whole rows
  EXPECT_TRUE(tets.deflate && tets.shuffle);
  EXPECT_EQ(tets.chunk[1], 4u);
  EXPECT_FALSE(tets.has_units);
  const auto boundary = shape_of(f.id, "/mesh/boundary_faces");
  EXPECT_EQ(boundary.layout, H5D_CONTIGUOUS);
  EXPECT_FALSE(boundary.has_units);
  // Energies are whole-body joules in 3-D (J/m, per metre of thickness, in 2-D).
  for (const char* energy :
       {"kinetic_energy", "elastic_energy", "dissipated_energy", "external_work"}) {
    EXPECT_EQ(shape_of(f.id, std::string("/timeseries/") + energy).units, "J") << energy;
  }
  EXPECT_EQ(shape_of(f.id, "/timeseries/center_mean_stress").units, "Pa");
  for (const auto& name : kFieldNames) {
    const auto s = shape_of(f.id, "/fields/frame_00001/" + name);
    EXPECT_EQ(s.layout, H5D_CONTIGUOUS) << name;
    EXPECT_TRUE(s.has_units) << name;
  }

  // The stored node vectors are the frame's N x 3 values as they are: z is data here.
  std::vector<double> xyz(3 * n);
  const hid_t ds = H5Dopen2(f.id, "/fields/frame_00001/displacement", H5P_DEFAULT);
  ASSERT_GE(ds, 0);
  ASSERT_GE(H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, xyz.data()), 0);
  H5Dclose(ds);
  expect_same_bits(xyz, make_frame(mesh, 1e-6, 1.0).displacement, "stored displacement");
  // And /mesh/nodes is (x, y, z) per row.
  std::vector<double> coordinates(3 * n), want;
  const hid_t nd = H5Dopen2(f.id, "/mesh/nodes", H5P_DEFAULT);
  ASSERT_GE(H5Dread(nd, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, coordinates.data()), 0);
  H5Dclose(nd);
  for (std::size_t i = 0; i < n; ++i) want.insert(want.end(), {mesh.x[i], mesh.y[i], mesh.z[i]});
  expect_same_bits(coordinates, want, "/mesh/nodes");
}

TEST(ResultFile3d, XdmfDescribesTetrahedraOnXyzNodes) {
  ScratchDir dir;
  const Mesh mesh = tet_box(3.0, 1.0, 1.0, 3, 1, 1);  // 16 nodes, 18 tetrahedra
  ASSERT_EQ(mesh.node_count(), 16u);
  ASSERT_EQ(mesh.element_count(), 18u);
  write_result(dir.str("frames"), mesh, {0.0, 0.1, 0.25}, make_history(3, 1));
  const std::string x = read_text(dir.str("frames/result.xdmf"));
  EXPECT_NE(x.find("CollectionType=\"Temporal\""), std::string::npos);
  EXPECT_NE(x.find("<Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"18\">"),
            std::string::npos);
  EXPECT_NE(x.find("<DataItem Dimensions=\"18 4\" DataType=\"Int\" Precision=\"4\" "
                   "Format=\"HDF\">result.h5:/mesh/tetrahedra</DataItem>"),
            std::string::npos);
  EXPECT_NE(x.find("<Geometry GeometryType=\"XYZ\">"), std::string::npos);
  EXPECT_NE(x.find("<DataItem Dimensions=\"16 3\" DataType=\"Float\" Precision=\"8\" "
                   "Format=\"HDF\">result.h5:/mesh/nodes</DataItem>"),
            std::string::npos);
  EXPECT_NE(x.find("<DataItem Dimensions=\"16 3\" DataType=\"Float\" Precision=\"8\" "
                   "Format=\"HDF\">result.h5:/fields/frame_00002/displacement</DataItem>"),
            std::string::npos);
  EXPECT_NE(x.find("<DataItem Dimensions=\"18\" DataType=\"Float\" Precision=\"8\" "
                   "Format=\"HDF\">result.h5:/fields/frame_00002/von_mises</DataItem>"),
            std::string::npos);
  EXPECT_EQ(x.find("Triangle"), std::string::npos);
  EXPECT_EQ(x.find("\"XY\""), std::string::npos);
  EXPECT_EQ(x.find("/mesh/triangles"), std::string::npos);

  // Without frames: one Uniform grid of the reference tetrahedra.
  write_result(dir.str("none"), mesh, {}, History{}, false, "failed before t = 0");
  const std::string bare = read_text(dir.str("none/result.xdmf"));
  EXPECT_NE(bare.find("<Grid Name=\"mesh\" GridType=\"Uniform\">"), std::string::npos);
  EXPECT_NE(bare.find("TopologyType=\"Tetrahedron\""), std::string::npos);
  EXPECT_NE(bare.find("GeometryType=\"XYZ\""), std::string::npos);
  ResultReader reader(dir.str("none/result.h5"));
  EXPECT_EQ(reader.info().dimension, 3);
  EXPECT_TRUE(reader.info().frame_times.empty());
  EXPECT_EQ(reader.mesh().tetrahedra, mesh.tetrahedra);
}

TEST(ResultFile3d, WriterRejectsMismatchedInputAndStaysUsable) {
  ScratchDir dir;
  const Mesh mesh = tet_box(1.0, 1.0, 1.0, 1, 1, 2);
  Mesh no_z = mesh;
  no_z.z.pop_back();
  EXPECT_THROW(ResultWriter(dir.str("a"), no_z, kSpec, "v"), std::invalid_argument);
  Mesh mixed = mesh;
  mixed.triangles = {{0, 1, 2}};
  EXPECT_THROW(ResultWriter(dir.str("b"), mixed, kSpec, "v"), std::invalid_argument);

  ResultWriter writer(dir.str("c"), mesh, kSpec, "v");
  FieldFrame flat = make_frame(mesh, 0.0, 0);
  flat.dimension = 2;  // a 2-D frame for a 3-D mesh
  EXPECT_THROW(writer.write_frame(flat), std::invalid_argument);
  FieldFrame short_vectors = make_frame(mesh, 0.0, 0);
  short_vectors.velocity.resize(2 * mesh.node_count());
  EXPECT_THROW(writer.write_frame(short_vectors), std::invalid_argument);
  writer.write_frame(make_frame(mesh, 0.0, 0));
  writer.finish(make_history(1, 0), make_summary(mesh), true, "");
  EXPECT_EQ(ResultReader(writer.h5_path()).info().frame_times.size(), 1u);

  // A 2-D writer refuses a 3-D frame, and a later mesh of the other dimension.
  const Mesh flat_mesh = two_triangles();
  ResultWriter writer2(dir.str("d"), flat_mesh, kSpec, "v", ResultWriter::MeshWrite::kLater);
  FieldFrame deep = make_frame(flat_mesh, 0.0, 0);
  deep.dimension = 3;
  EXPECT_THROW(writer2.write_frame(deep), std::invalid_argument);
  Mesh tets_with_four_nodes;
  tets_with_four_nodes.x = {0, 1, 0, 0};
  tets_with_four_nodes.y = {0, 0, 1, 0};
  tets_with_four_nodes.z = {0, 0, 0, 1};
  tets_with_four_nodes.tetrahedra = {{0, 1, 2, 3}, {0, 1, 2, 3}};  // 4 nodes, 2 elements
  EXPECT_THROW(writer2.write_mesh(tets_with_four_nodes), std::invalid_argument);
}

// A mesh whose boundary faces were not found (no 3-D finalize yet) is written and read with an
// empty 0 x 3 /mesh/boundary_faces.
TEST(ResultFile3d, EmptyBoundaryFacesAreAllowed) {
  ScratchDir dir;
  Mesh mesh = tet_box(1.0, 1.0, 1.0, 2, 1, 1);
  mesh.boundary_faces.clear();
  write_result(dir.str(), mesh, {0.0}, make_history(1, 0));
  {
    H5File f(dir.str("result.h5"));
    EXPECT_EQ(shape_of(f.id, "/mesh/boundary_faces").dims, (std::vector<hsize_t>{0, 3}));
  }
  ResultReader reader(dir.str("result.h5"));
  const Mesh back = reader.mesh();
  EXPECT_TRUE(back.boundary_faces.empty());
  EXPECT_EQ(back.tetrahedra, mesh.tetrahedra);
  expect_same_bits(reader.field(0, "displacement"), make_frame(mesh, 0.0, 0).displacement, "u");
}

// The reader names what is wrong with a 3-D file rather than hand out a Mesh that sends loops
// out of bounds.
TEST(ResultFile3d, ReaderChecksTheStoredMesh) {
  ScratchDir dir;
  const Mesh mesh = tet_box(1.0, 1.0, 1.0, 1, 1, 1);  // 8 nodes
  const auto rewrite = [&](const std::string& sub, auto&& change) {
    write_result(dir.str(sub), mesh, {0.0}, make_history(1, 0));
    const hid_t file = H5Fopen(dir.str(sub + "/result.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    change(file);
    H5Fclose(file);
  };
  const auto message = [](auto&& call) -> std::string {
    try {
      call();
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "<no exception>";
  };
  rewrite("index", [](hid_t file) {
    const int32_t bad[4] = {0, 1, 2, 8};
    const hid_t ds = H5Dopen2(file, "/mesh/tetrahedra", H5P_DEFAULT);
    const hsize_t start[2] = {0, 0}, count[2] = {1, 4};
    const hid_t space = H5Dget_space(ds);
    H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr);
    const hid_t memory = H5Screate_simple(2, count, nullptr);
    EXPECT_GE(H5Dwrite(ds, H5T_NATIVE_INT32, memory, space, H5P_DEFAULT, bad), 0);
    H5Sclose(memory);
    H5Sclose(space);
    H5Dclose(ds);
  });
  ResultReader bad_index(dir.str("index/result.h5"));
  EXPECT_NE(message([&] { bad_index.mesh(); }).find("/mesh/tetrahedra entry 3 is node 8 of 8"),
            std::string::npos);

  rewrite("faces", [](hid_t file) { H5Ldelete(file, "/mesh/boundary_faces", H5P_DEFAULT); });
  ResultReader no_faces(dir.str("faces/result.h5"));
  EXPECT_NE(message([&] { no_faces.mesh(); }).find("no dataset /mesh/boundary_faces"),
            std::string::npos);

  rewrite("dimension", [](hid_t file) {
    const int32_t four = 4;
    const hid_t a = H5Aopen(file, "dimension", H5P_DEFAULT);
    EXPECT_GE(H5Awrite(a, H5T_NATIVE_INT32, &four), 0);
    H5Aclose(a);
  });
  EXPECT_NE(message([&] {
              ResultReader r(dir.str("dimension/result.h5"));
            }).find("has dimension 4, expected 2 or 3"),
            std::string::npos);
}

}  // namespace
}  // namespace softshock
