// Result files: exact round trip through ResultWriter/ResultReader, the documented HDF5 layout
// (docs/results-format.md), the temporary-file protocol, concurrency, the 3-D round trip (more
// of 3-D in test_result_file_3d.cpp, linked into the same binary), and (built separately as
// test_result_file_meshio, label integration) the XDMF companion read by meshio and checked for
// ParaView, 2-D and 3-D. Shared helpers: result_file_helpers.hpp; the tetrahedral box: tet_box.hpp.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "result_file_helpers.hpp"
#include "scratch_dir.hpp"
#include "solver/io/result_file.hpp"
#include "tet_box.hpp"

namespace softshock {
namespace {

namespace fs = std::filesystem;

// ScratchDir(prefix): tests/solver/scratch_dir.hpp.
class ScratchDir : public testing::ScratchDir {
 public:
  ScratchDir() : testing::ScratchDir("result") {}
};

using namespace testing;  // softshock::testing: the helpers

#ifndef SOFTSHOCK_RESULT_FILE_INTEGRATION

// ---- round trip ----------------------------------------------------------------------------

TEST(ResultFile, RoundTripIsExact) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  const std::vector<double> times = {0.0, 1e-5 / 3.0, 2.5e-5};
  const History history = make_history(7, 4);
  write_result(dir.str(), mesh, times, history);

  ResultReader reader(dir.str("result.h5"));
  const ResultInfo& info = reader.info();
  EXPECT_TRUE(info.complete);
  EXPECT_EQ(info.error, "");
  EXPECT_EQ(info.spec_json, kSpec);
  EXPECT_EQ(info.summary_json, summary_to_json(make_summary(mesh)));
  EXPECT_EQ(info.solver_version, "0.1.0-test");
  expect_same_bits(info.frame_times, times, "frame_times");
  EXPECT_EQ(info.nodes, 4u);
  EXPECT_EQ(info.elements, 2u);

  const Mesh back = reader.mesh();
  EXPECT_EQ(back.x, mesh.x);
  EXPECT_EQ(back.y, mesh.y);
  EXPECT_EQ(back.triangles, mesh.triangles);
  EXPECT_EQ(back.boundary_nodes, mesh.boundary_nodes);
  EXPECT_EQ(back.boundary_edges.size(), mesh.boundary_edges.size());

  std::vector<std::string> expected_names;
  for (const auto& [name, column] : history.columns()) {
    expected_names.push_back(name);
    expect_same_bits(reader.series(name), *column, name);
  }
  EXPECT_EQ(reader.series_names(), expected_names);  // History::columns() order
  expect_same_bits(reader.mode_times(), history.time, "mode_times");
  std::size_t rows = 0, cols = 0;
  const auto amplitudes = reader.mode_amplitudes(rows, cols);
  EXPECT_EQ(rows, 7u);
  EXPECT_EQ(cols, 5u);
  std::vector<double> flat;
  for (const auto& row : history.modes) flat.insert(flat.end(), row.begin(), row.end());
  expect_same_bits(amplitudes, flat, "amplitudes");

  for (std::size_t k = 0; k < times.size(); ++k) {
    const FieldFrame want = make_frame(mesh, times[k], static_cast<double>(k));
    for (const auto& name : kFieldNames) {
      expect_same_bits(reader.field(k, name), field_of(want, name),
                       name + " of frame " + std::to_string(k));
    }
  }
  EXPECT_THROW(reader.field(3, "J"), std::out_of_range);
  EXPECT_THROW(reader.field(0, "pressure"), std::invalid_argument);
  EXPECT_THROW(reader.series("no_such_series"), std::runtime_error);
  EXPECT_THROW(reader.series("../mesh/nodes"), std::invalid_argument);
}

TEST(ResultFile, IncompleteRunKeepsFlagAndError) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  const std::string message = "t = 1.2e-05 s: element 1 inverted (J = -0.03)";
  write_result(dir.str(), mesh, {0.0}, make_history(2, 2), false, message);
  ResultReader reader(dir.str("result.h5"));
  EXPECT_FALSE(reader.info().complete);
  EXPECT_EQ(reader.info().error, message);
  EXPECT_EQ(reader.info().frame_times.size(), 1u);
}

TEST(ResultFile, RunWithoutFramesOrSamplesIsReadable) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  write_result(dir.str(), mesh, {}, History{}, false, "failed before the first step");
  ResultReader reader(dir.str("result.h5"));
  EXPECT_TRUE(reader.info().frame_times.empty());
  EXPECT_TRUE(reader.series("time").empty());
  std::size_t rows = 9, cols = 9;
  EXPECT_TRUE(reader.mode_amplitudes(rows, cols).empty());
  EXPECT_EQ(rows, 0u);
  EXPECT_EQ(cols, 0u);
  EXPECT_TRUE(fs::exists(dir.path() / "result.xdmf"));
}

TEST(ResultFile, LargeStringsRoundTrip) {
  // Past HDF5's 64 KiB object-header limit for attributes stored inline.
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  std::string spec = "{\"pad\":\"";
  spec.append(1 << 20, 'x');
  spec += "\"}";
  {
    ResultWriter writer(dir.str(), mesh, spec, "v");
    writer.finish(History{}, make_summary(mesh), true, std::string(100000, 'e'));
  }
  ResultReader reader(dir.str("result.h5"));
  EXPECT_EQ(reader.info().spec_json, spec);
  EXPECT_EQ(reader.info().error.size(), 100000u);
}

// ---- temporary file protocol --------------------------------------------------------------

TEST(ResultFile, NothingUnderTheFinalNameBeforeFinish) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  const std::string out = dir.str("nested/run-1");  // created by the writer
  ResultWriter writer(out, mesh, kSpec, "v");
  writer.write_frame(make_frame(mesh, 0.0, 0));
  EXPECT_EQ(writer.h5_path(), out + "/result.h5");
  EXPECT_EQ(writer.xdmf_path(), out + "/result.xdmf");
  EXPECT_FALSE(fs::exists(writer.h5_path()));
  EXPECT_FALSE(fs::exists(writer.xdmf_path()));
  EXPECT_TRUE(fs::exists(out + "/result.h5.tmp"));
  writer.finish(make_history(3, 1), make_summary(mesh), true, "");
  EXPECT_TRUE(fs::exists(writer.h5_path()));
  EXPECT_TRUE(fs::exists(writer.xdmf_path()));
  EXPECT_FALSE(fs::exists(out + "/result.h5.tmp"));
  EXPECT_FALSE(fs::exists(out + "/result.xdmf.tmp"));
  EXPECT_THROW(writer.write_frame(make_frame(mesh, 1.0, 1)), std::logic_error);
  EXPECT_THROW(writer.finish(History{}, make_summary(mesh), true, ""), std::logic_error);
}

TEST(ResultFile, WriterDestroyedWithoutFinishLeavesNothing) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  {
    ResultWriter writer(dir.str(), mesh, kSpec, "v");
    writer.write_frame(make_frame(mesh, 0.0, 0));
    writer.write_frame(make_frame(mesh, 1.0, 1));
  }
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

// MeshWrite::kLater (the writer thread's way): /mesh comes from write_mesh(), once, with the mesh
// the writer was made for, before finish() -- a file without its mesh is never named complete.
TEST(ResultFile, ALaterMeshIsWrittenOnceAndFinishWaitsForIt) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  {
    ResultWriter writer(dir.str("a"), mesh, kSpec, "v", ResultWriter::MeshWrite::kLater);
    writer.write_frame(make_frame(mesh, 0.0, 0));
    EXPECT_THROW(writer.finish(make_history(1, 0), make_summary(mesh), true, ""), std::logic_error);
    EXPECT_THROW(writer.write_mesh(make_rectangle_mesh(1.0, 1.0, 2, 2)), std::invalid_argument);
    writer.write_mesh(mesh);
    EXPECT_THROW(writer.write_mesh(mesh), std::logic_error);
    writer.finish(make_history(1, 0), make_summary(mesh), true, "");
  }
  const Mesh back = ResultReader(dir.str("a/result.h5")).mesh();
  EXPECT_EQ(back.x, mesh.x);
  EXPECT_EQ(back.y, mesh.y);
  EXPECT_EQ(back.triangles, mesh.triangles);
  EXPECT_EQ(back.boundary_nodes, mesh.boundary_nodes);
  { ResultWriter unfinished(dir.str("b"), mesh, kSpec, "v", ResultWriter::MeshWrite::kLater); }
  EXPECT_TRUE(fs::is_empty(dir.path() / "b"));
}

TEST(ResultFile, RewriteReplacesEarlierResult) {
  // A requeued job writes into the folder of its interrupted attempt.
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  write_result(dir.str(), mesh, {0.0}, make_history(1, 0), false, "interrupted");
  write_result(dir.str(), mesh, {0.0, 1.0}, make_history(2, 0), true, "");
  ResultReader reader(dir.str("result.h5"));
  EXPECT_TRUE(reader.info().complete);
  EXPECT_EQ(reader.info().frame_times.size(), 2u);
}

TEST(ResultFile, RejectsInconsistentInputAndStaysUsable) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  ResultWriter writer(dir.str(), mesh, kSpec, "v");
  FieldFrame bad = make_frame(mesh, 0.0, 0);
  bad.hoop_stress.pop_back();
  EXPECT_THROW(writer.write_frame(bad), std::invalid_argument);
  writer.write_frame(make_frame(mesh, 0.0, 0));  // still usable, still frame_00000

  History ragged = make_history(3, 2);
  ragged.abar.pop_back();
  EXPECT_THROW(writer.finish(ragged, make_summary(mesh), true, ""), std::invalid_argument);
  History bad_modes = make_history(3, 2);
  bad_modes.modes[1].pop_back();
  EXPECT_THROW(writer.finish(bad_modes, make_summary(mesh), true, ""), std::invalid_argument);
  EXPECT_FALSE(fs::exists(writer.h5_path()));

  writer.finish(make_history(3, 2), make_summary(mesh), true, "");
  ResultReader reader(writer.h5_path());
  EXPECT_EQ(reader.info().frame_times, std::vector<double>{0.0});
}

TEST(ResultFile, MissingOrForeignFileThrowsWithPath) {
  ScratchDir dir;
  const std::string missing = dir.str("no-such-run/result.h5");
  try {
    ResultReader reader(missing);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  const std::string garbage = dir.str("result.h5");
  std::ofstream(garbage) << "not an HDF5 file\n";
  try {
    ResultReader reader(garbage);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(garbage), std::string::npos) << e.what();
  }
}

TEST(ResultFile, UnwritableDirectoryThrowsWithPath) {
  ScratchDir dir;
  std::ofstream(dir.str("plain-file")) << "x";
  const std::string out = dir.str("plain-file/run");  // a file where a folder should be
  try {
    ResultWriter writer(out, two_triangles(), kSpec, "v");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(out), std::string::npos) << e.what();
  }
}

// ---- concurrency ---------------------------------------------------------------------------

TEST(ResultFile, TwoWritersAndAReaderInParallel) {
  // Correctness under concurrent use. (Debian's libhdf5 is built thread-safe and serialises
  // calls itself, so on this platform the test cannot tell whether our own mutex is there.)
  ScratchDir dir;
  const Mesh mesh = make_rectangle_mesh(1.0, 0.5, 24, 12);
  const History history = make_history(500, 8);
  std::vector<double> times;
  for (int k = 0; k < 12; ++k) times.push_back(1e-6 * k);
  write_result(dir.str("reference"), mesh, times, history);

  std::atomic<bool> writers_done{false};
  std::atomic<int> reads{0};
  std::vector<std::string> errors(3);
  auto writer_task = [&](int w) {
    try {
      write_result(dir.str("run-" + std::to_string(w)), mesh, times, history);
    } catch (const std::exception& e) {
      errors[w] = e.what();
    }
  };
  std::thread reader_thread([&] {
    try {
      const FieldFrame want = make_frame(mesh, times[5], 5.0);
      do {
        ResultReader reader(dir.str("reference/result.h5"));
        if (reader.field(5, "velocity") != want.velocity) throw std::runtime_error("mismatch");
        if (reader.series("abar").size() != 500) throw std::runtime_error("short series");
        ++reads;
      } while (!writers_done);
    } catch (const std::exception& e) {
      errors[2] = e.what();
    }
  });
  std::thread w0(writer_task, 0), w1(writer_task, 1);
  w0.join();
  w1.join();
  writers_done = true;
  reader_thread.join();
  for (const auto& e : errors) EXPECT_EQ(e, "");
  EXPECT_GT(reads.load(), 0);
  for (int w = 0; w < 2; ++w) {
    ResultReader reader(dir.str("run-" + std::to_string(w) + "/result.h5"));
    ASSERT_EQ(reader.info().frame_times, times);
    for (std::size_t k = 0; k < times.size(); ++k) {
      const FieldFrame want = make_frame(mesh, times[k], static_cast<double>(k));
      for (const auto& name : kFieldNames) {
        expect_same_bits(reader.field(k, name), field_of(want, name), name);
      }
    }
  }
}

// ---- the documented layout, read with the plain HDF5 API ------------------------------------

TEST(ResultFile, LayoutMatchesTheDocumentedContract) {
  ScratchDir dir;
  // 48 x 24 cells: 1225 nodes (N x 2 doubles = 19.6 KB, chunked), 2304 elements (18.4 KB,
  // chunked), a 144-node boundary loop (contiguous).
  const Mesh mesh = make_rectangle_mesh(2.0, 1.0, 48, 24);
  write_result(dir.str(), mesh, {0.0, 1e-6, 2e-6}, make_history(4000, 6));
  H5File f(dir.str("result.h5"));
  ASSERT_GE(f.id, 0);

  EXPECT_EQ(attr_type(f.id, "format_version"), std::make_pair(H5T_INTEGER, std::size_t{4}));
  EXPECT_EQ(attr_type(f.id, "complete"), std::make_pair(H5T_INTEGER, std::size_t{4}));
  EXPECT_EQ(attr_type(f.id, "steps"), std::make_pair(H5T_INTEGER, std::size_t{8}));
  EXPECT_EQ(attr_type(f.id, "frame_count"), std::make_pair(H5T_INTEGER, std::size_t{8}));
  EXPECT_EQ(attr_type(f.id, "wall_time_s"), std::make_pair(H5T_FLOAT, std::size_t{8}));
  for (const char* s : {"spec", "solver_version", "error", "summary"}) {
    EXPECT_EQ(attr_type(f.id, s).first, H5T_STRING) << s;
  }
  EXPECT_EQ(string_attr(f.id, "spec"), kSpec);
  {
    int64_t steps = 0, frames = 0;
    int32_t version = 0;
    const hid_t a = H5Aopen(f.id, "steps", H5P_DEFAULT);
    H5Aread(a, H5T_NATIVE_INT64, &steps);
    H5Aclose(a);
    const hid_t b = H5Aopen(f.id, "frame_count", H5P_DEFAULT);
    H5Aread(b, H5T_NATIVE_INT64, &frames);
    H5Aclose(b);
    const hid_t c = H5Aopen(f.id, "format_version", H5P_DEFAULT);
    H5Aread(c, H5T_NATIVE_INT32, &version);
    H5Aclose(c);
    EXPECT_EQ(steps, 123456789012);
    EXPECT_EQ(frames, 3);
    EXPECT_EQ(version, 2);
  }

  const hsize_t n = mesh.node_count(), e = mesh.element_count();
  const auto nodes = shape_of(f.id, "/mesh/nodes");
  EXPECT_EQ(nodes.type_class, H5T_FLOAT);
  EXPECT_EQ(nodes.type_size, 8u);
  EXPECT_EQ(nodes.dims, (std::vector<hsize_t>{n, 2}));
  EXPECT_EQ(nodes.units, "m");
  const auto tris = shape_of(f.id, "/mesh/triangles");
  EXPECT_EQ(tris.type_class, H5T_INTEGER);
  EXPECT_EQ(tris.type_size, 4u);
  EXPECT_EQ(tris.dims, (std::vector<hsize_t>{e, 3}));
  // Connectivity compresses to ~0.27 and is written once: chunked, shuffle + deflate.
  ASSERT_EQ(tris.layout, H5D_CHUNKED);
  EXPECT_TRUE(tris.deflate && tris.shuffle);
  const auto loop = shape_of(f.id, "/mesh/boundary_nodes");
  EXPECT_EQ(loop.type_class, H5T_INTEGER);
  EXPECT_EQ(loop.type_size, 4u);
  EXPECT_EQ(loop.dims, (std::vector<hsize_t>{mesh.boundary_nodes.size()}));
  EXPECT_EQ(loop.layout, H5D_CONTIGUOUS);  // small: not worth a chunk index

  // Every series: float64, T samples, a known unit. A new History column needs its unit in
  // series_units() (solver/io/result_writer.cpp) and a line in docs/results-format.md.
  const History names_only;
  for (const auto& [name, column] : names_only.columns()) {
    const auto s = shape_of(f.id, "/timeseries/" + name);
    EXPECT_EQ(s.type_class, H5T_FLOAT) << name;
    EXPECT_EQ(s.type_size, 8u) << name;
    EXPECT_EQ(s.dims, std::vector<hsize_t>{4000}) << name;
    EXPECT_FALSE(s.units.empty()) << name << " has no units";
    EXPECT_EQ(s.layout, H5D_CONTIGUOUS) << name;  // floating point: stored raw
  }
  EXPECT_EQ(shape_of(f.id, "/modes/time").dims, std::vector<hsize_t>{4000});
  EXPECT_EQ(shape_of(f.id, "/modes/amplitude").dims, (std::vector<hsize_t>{4000, 7}));

  for (int k = 0; k < 3; ++k) {
    char group[64];
    std::snprintf(group, sizeof group, "/fields/frame_%05d", k);
    const hid_t g = H5Gopen2(f.id, group, H5P_DEFAULT);
    ASSERT_GE(g, 0) << group;
    EXPECT_EQ(attr_type(g, "time"), std::make_pair(H5T_FLOAT, std::size_t{8}));
    H5Gclose(g);
    for (const auto& name : kFieldNames) {
      const auto s = shape_of(f.id, std::string(group) + "/" + name);
      const bool nodal = name == "displacement" || name == "velocity";
      EXPECT_EQ(s.type_class, H5T_FLOAT) << name;
      EXPECT_EQ(s.type_size, 8u) << name;
      // Node vectors are N x 3 (z = 0) since format_version 2: ParaView's Warp By Vector.
      const std::vector<hsize_t> dims =
          nodal ? std::vector<hsize_t>{n, 3} : std::vector<hsize_t>{e};
      EXPECT_EQ(s.dims, dims) << name;
      EXPECT_TRUE(s.has_units) << name;
      // Solver fields keep 0.78-0.87 of their size under shuffle + deflate at ~20x the CPU of
      // writing them raw (docs/results-format.md): stored contiguous and unfiltered.
      EXPECT_EQ(s.layout, H5D_CONTIGUOUS) << name;
      EXPECT_FALSE(s.deflate || s.shuffle) << name;
    }
  }
}

// The stored N x 3 vector holds the (x, y) pairs bit for bit and an exact zero z column.
TEST(ResultFile, NodeVectorsAreStoredWithAZeroZColumn) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  write_result(dir.str(), mesh, {0.0, 0.5}, make_history(2, 1));
  H5File f(dir.str("result.h5"));
  ASSERT_GE(f.id, 0);
  const std::size_t n = mesh.node_count();
  for (const char* name : {"displacement", "velocity"}) {
    const std::string path = std::string("/fields/frame_00001/") + name;
    ASSERT_EQ(shape_of(f.id, path).dims, (std::vector<hsize_t>{n, 3})) << name;
    std::vector<double> xyz(3 * n, 1.0);
    const hid_t ds = H5Dopen2(f.id, path.c_str(), H5P_DEFAULT);
    ASSERT_GE(ds, 0) << path;
    ASSERT_GE(H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, xyz.data()), 0);
    H5Dclose(ds);
    const std::vector<double> want = field_of(make_frame(mesh, 0.5, 1.0), name);
    std::vector<double> xy, z;
    for (std::size_t i = 0; i < n; ++i) {
      xy.insert(xy.end(), {xyz[3 * i], xyz[3 * i + 1]});
      z.push_back(xyz[3 * i + 2]);
    }
    expect_same_bits(xy, want, path);
    expect_same_bits(z, std::vector<double>(n, 0.0), path + " z");
  }
}

// Files written before format_version 2 (node vectors N x 2) still read, with the same values.
TEST(ResultFile, ReadsFormatVersion1NodeVectors) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  write_result(dir.str(), mesh, {0.0}, make_history(2, 1));
  const std::vector<double> disp = make_frame(mesh, 0.0, 0.0).displacement;
  {
    // Rewrite the file as version 1 wrote it: N x 2 displacement, format_version 1.
    const hid_t file = H5Fopen(dir.str("result.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    ASSERT_GE(H5Ldelete(file, "/fields/frame_00000/displacement", H5P_DEFAULT), 0);
    const hsize_t dims[2] = {mesh.node_count(), 2};
    const hid_t space = H5Screate_simple(2, dims, nullptr);
    const hid_t ds = H5Dcreate2(file, "/fields/frame_00000/displacement", H5T_IEEE_F64LE, space,
                                H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, disp.data()), 0);
    H5Dclose(ds);
    H5Sclose(space);
    const int32_t one = 1;
    const hid_t a = H5Aopen(file, "format_version", H5P_DEFAULT);
    ASSERT_GE(H5Awrite(a, H5T_NATIVE_INT32, &one), 0);
    H5Aclose(a);
    H5Fclose(file);
  }
  ResultReader reader(dir.str("result.h5"));
  expect_same_bits(reader.field(0, "displacement"), disp, "version 1 displacement");
  expect_same_bits(reader.field(0, "velocity"), make_frame(mesh, 0.0, 0.0).velocity, "velocity");
}

TEST(ResultFile, XdmfPointsAtTheFramesOfTheHdf5File) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  write_result(dir.str(), mesh, {0.0, 0.1, 0.25}, make_history(3, 1));
  std::ifstream in(dir.str("result.xdmf"));
  std::stringstream text;
  text << in.rdbuf();
  const std::string x = text.str();
  EXPECT_NE(x.find("<Xdmf Version=\"3.0\">"), std::string::npos);
  EXPECT_NE(x.find("CollectionType=\"Temporal\""), std::string::npos);
  EXPECT_NE(x.find("<Time Value=\"0.25\"/>"), std::string::npos);
  EXPECT_NE(x.find("result.h5:/mesh/nodes"), std::string::npos);
  EXPECT_NE(x.find("result.h5:/fields/frame_00002/von_mises"), std::string::npos);
  EXPECT_EQ(x.find("frame_00003"), std::string::npos);
}

// A 2-D file holds exactly what it held before 3-D results existed (nodes N x 2, triangles,
// the outer loop, node vectors N x 3 with z = 0): the root attribute `dimension` = 2 is the
// only addition.
TEST(ResultFile, TwoDimensionalLayoutIsUnchangedButForTheDimensionAttribute) {
  ScratchDir dir;
  const Mesh mesh = make_rectangle_mesh(1.0, 0.5, 6, 3);
  write_result(dir.str(), mesh, {0.0, 1e-6}, make_history(5, 2));
  H5File f(dir.str("result.h5"));
  ASSERT_GE(f.id, 0);
  const std::size_t n = mesh.node_count(), e = mesh.element_count();
  const std::string b = std::to_string(mesh.boundary_nodes.size());
  EXPECT_EQ(sorted_objects(f.id),
            expected_layout(n, e, 2, 5, 2,
                            {"boundary_nodes int32 [" + b + "]",
                             "nodes float64 [" + std::to_string(n) + " x 2]",
                             "triangles int32 [" + std::to_string(e) + " x 3]"}));
  EXPECT_EQ(attribute_names(f.id), kRootAttributes);
  EXPECT_EQ(attr_type(f.id, "dimension"), std::make_pair(H5T_INTEGER, std::size_t{4}));
  EXPECT_EQ(int_attr(f.id, "dimension"), 2);
  EXPECT_EQ(int_attr(f.id, "format_version"), 2);
  EXPECT_EQ(shape_of(f.id, "/timeseries/kinetic_energy").units, "J/m");  // plane strain
}

// Files written before 3-D results have no `dimension`: they read as 2-D, as before.
TEST(ResultFile, AFileWithoutADimensionAttributeReadsAs2d) {
  ScratchDir dir;
  const Mesh mesh = two_triangles();
  write_result(dir.str(), mesh, {0.0}, make_history(2, 1));
  {
    const hid_t file = H5Fopen(dir.str("result.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    ASSERT_GE(H5Adelete(file, "dimension"), 0);
    H5Fclose(file);
  }
  ResultReader reader(dir.str("result.h5"));
  EXPECT_EQ(reader.info().dimension, 2);
  EXPECT_EQ(reader.info().elements, 2u);
  EXPECT_EQ(reader.mesh().triangles, mesh.triangles);
  expect_same_bits(reader.field(0, "velocity"), make_frame(mesh, 0.0, 0.0).velocity, "velocity");
}

// ---- 3-D results (tetrahedra; layout, XDMF and errors in test_result_file_3d.cpp) -------------

TEST(ResultFile3d, RoundTripIsExact) {
  ScratchDir dir;
  // Two cubes of six tetrahedra: 12 nodes, 12 tetrahedra, 10 squares of surface = 20 faces.
  const Mesh mesh = tet_box(2.0, 1.0, 1.0 / 3.0, 2, 1, 1);
  ASSERT_EQ(mesh.dimension(), 3);
  ASSERT_EQ(mesh.boundary_faces.size(), 20u);
  const std::vector<double> times = {0.0, 1e-5 / 3.0, 2.5e-5};
  const History history = make_history(6, 3);
  write_result(dir.str(), mesh, times, history);

  ResultReader reader(dir.str("result.h5"));
  const ResultInfo& info = reader.info();
  EXPECT_EQ(info.dimension, 3);
  EXPECT_EQ(info.nodes, 12u);
  EXPECT_EQ(info.elements, 12u);
  EXPECT_TRUE(info.complete);
  expect_same_bits(info.frame_times, times, "frame_times");

  const Mesh back = reader.mesh();
  EXPECT_EQ(back.dimension(), 3);
  expect_same_bits(back.x, mesh.x, "x");
  expect_same_bits(back.y, mesh.y, "y");
  expect_same_bits(back.z, mesh.z, "z");
  EXPECT_EQ(back.tetrahedra, mesh.tetrahedra);
  EXPECT_EQ(back.boundary_faces, mesh.boundary_faces);
  EXPECT_TRUE(back.triangles.empty() && back.boundary_edges.empty() && back.boundary_nodes.empty());

  for (std::size_t k = 0; k < times.size(); ++k) {
    const FieldFrame want = make_frame(mesh, times[k], static_cast<double>(k));
    ASSERT_EQ(want.displacement.size(), 3 * mesh.node_count());
    for (const auto& name : kFieldNames) {
      expect_same_bits(reader.field(k, name), field_of(want, name),
                       name + " of frame " + std::to_string(k));
    }
  }
  for (const auto& [name, column] : history.columns()) {
    expect_same_bits(reader.series(name), *column, name);
  }
}

#else  // SOFTSHOCK_RESULT_FILE_INTEGRATION

// ---- XDMF read by meshio (Debian's python3-meshio), as users and post-processing do ---------

// Exit status of a command; the test fails with the command line when it is not 0.
void expect_command_succeeds(const std::string& cmd) {
  const int rc = std::system(cmd.c_str());
  ASSERT_NE(rc, -1) << cmd;
  EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << cmd << " -> " << rc;
}

// tests/integration/check_xdmf_meshio.py on a result of `mesh` with frames at `times`.
void expect_meshio_reads(const Mesh& mesh, const std::vector<double>& times) {
  ScratchDir dir;
  write_result(dir.str(), mesh, times, make_history(5, 3));
  std::ostringstream cmd;
  cmd.precision(17);
  cmd << "/usr/bin/python3 " << SOFTSHOCK_SOURCE_DIR << "/tests/integration/check_xdmf_meshio.py "
      << "--dimension " << mesh.dimension() << " " << dir.str("result.xdmf") << " "
      << mesh.node_count() << " " << mesh.element_count();
  for (double t : times) cmd << " " << t;
  expect_command_succeeds(cmd.str());
}

TEST(ResultFileXdmf, MeshioReadsMeshAndFrames) {
  expect_meshio_reads(make_rectangle_mesh(1.0, 0.5, 8, 4), {0.0, 1e-5 / 3.0, 2.0e-5});
}

// 3-D: one "tetra" block on (x, y, z) points, node vectors N x 3 whose z is the frame's.
TEST(ResultFileXdmf, MeshioReadsTetrahedraAndFrames) {
  expect_meshio_reads(tet_box(1.0, 0.5, 0.25, 4, 2, 2), {0.0, 1e-5 / 3.0, 2.0e-5});
}

// What ParaView's default reader needs (3-component node vectors, Triangle on XY or Tetrahedron
// on XYZ topology, one temporal collection), checked on the XML and against the HDF5 shapes; 2-D
// and 3-D, with frames and (3-D) without.
TEST(ResultFileXdmf, StructureSuitsParaViewsDefaultReader) {
  ScratchDir dir;
  const Mesh tets = tet_box(1.0, 0.5, 0.25, 4, 2, 2);
  write_result(dir.str("2d"), make_rectangle_mesh(1.0, 0.5, 8, 4), {0.0, 1e-5, 2e-5},
               make_history(5, 3));
  write_result(dir.str("3d"), tets, {0.0, 1e-5, 2e-5}, make_history(5, 3));
  write_result(dir.str("3d-bare"), tets, {}, History{}, false, "failed before t = 0");
  for (const char* run : {"2d", "3d", "3d-bare"}) {
    expect_command_succeeds(std::string("/usr/bin/python3 ") + SOFTSHOCK_SOURCE_DIR +
                            "/tests/integration/check_xdmf_structure.py " +
                            dir.str(std::string(run) + "/result.xdmf"));
  }
}

#endif  // SOFTSHOCK_RESULT_FILE_INTEGRATION

}  // namespace
}  // namespace softshock
