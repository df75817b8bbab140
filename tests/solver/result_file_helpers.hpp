// Shared by the result-file tests (test_result_file.cpp, its unit and meshio builds): frames,
// histories and summaries whose values catch a lossy path, bitwise comparison, a whole result
// written in one call, and a test-side look at a file through the plain HDF5 API.
#pragma once

#include <gtest/gtest.h>
#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "solver/io/result_file.hpp"

namespace softshock::testing {

// Two triangles on the unit square, counter-clockwise, as finalize_mesh leaves them.
inline Mesh two_triangles() {
  Mesh mesh;
  mesh.x = {0.0, 1.0, 1.0, 0.0};
  mesh.y = {0.0, 0.0, 1.0, 1.0};
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  finalize_mesh(mesh);
  return mesh;
}

// Values that catch a lossy path (float32, text): non-terminating binary fractions, signed
// zero, subnormal and huge magnitudes.
inline double probe_value(std::size_t i, double salt) {
  switch (i % 5) {
    case 0:
      return salt / 3.0 + static_cast<double>(i);
    case 1:
      return -0.0;
    case 2:
      return 4.9e-324 * static_cast<double>(i);
    case 3:
      return -1.0e300 / (salt + 7.0);
    default:
      return std::nextafter(1.0, 2.0) * salt - static_cast<double>(i) / 7.0;
  }
}

// Node vectors N x dimension (3-D: a z column as busy as x and y), element fields E.
inline FieldFrame make_frame(const Mesh& mesh, double time_s, double salt) {
  FieldFrame f;
  f.time_s = time_s;
  f.dimension = mesh.dimension();
  const std::size_t n = mesh.node_count(), e = mesh.element_count();
  for (std::size_t i = 0; i < static_cast<std::size_t>(f.dimension) * n; ++i) {
    f.displacement.push_back(probe_value(i, salt));
    f.velocity.push_back(probe_value(i + 1, salt + 1));
  }
  for (std::size_t i = 0; i < e; ++i) {
    f.J.push_back(1.0 + probe_value(i, salt) * 1e-3);
    f.mean_stress.push_back(probe_value(i + 2, salt));
    f.radial_stress.push_back(probe_value(i + 3, salt));
    f.hoop_stress.push_back(probe_value(i + 4, salt));
    f.von_mises.push_back(std::abs(probe_value(i, salt + 2)));
    f.aspect_ratio.push_back(1.2 + std::abs(probe_value(i, salt + 3)));
  }
  return f;
}

// Fills every series History::columns() names, so the test follows new columns by itself.
inline History make_history(std::size_t samples, std::size_t modes) {
  History h;
  const auto columns = h.columns();
  for (std::size_t c = 0; c < columns.size(); ++c) {
    auto* column = const_cast<std::vector<double>*>(columns[c].second);
    for (std::size_t k = 0; k < samples; ++k) {
      column->push_back(columns[c].first == "time" ? 1e-6 * static_cast<double>(k) / 3.0
                                                   : probe_value(k, static_cast<double>(c)));
    }
  }
  for (std::size_t k = 0; k < samples && modes > 0; ++k) {
    std::vector<double> row;
    for (std::size_t m = 0; m <= modes; ++m) row.push_back(probe_value(k + m, 0.25));
    h.modes.push_back(std::move(row));
  }
  return h;
}

inline RunSummary make_summary(const Mesh& mesh) {
  RunSummary s;
  s.nodes = mesh.node_count();
  s.elements = mesh.element_count();
  s.steps = 123456789012;
  s.wall_time_s = 12.5;
  s.end_time_s = 1e-3;
  s.status = "completed";
  s.rim_reflections_s = {1e-4, 2e-4};
  return s;
}

inline const std::vector<std::string> kFieldNames = {"displacement", "velocity",      "J",
                                                     "mean_stress",  "radial_stress", "hoop_stress",
                                                     "von_mises",    "aspect_ratio"};

inline std::vector<double> field_of(const FieldFrame& f, const std::string& name) {
  if (name == "displacement") return f.displacement;
  if (name == "velocity") return f.velocity;
  if (name == "J") return f.J;
  if (name == "mean_stress") return f.mean_stress;
  if (name == "radial_stress") return f.radial_stress;
  if (name == "hoop_stress") return f.hoop_stress;
  if (name == "aspect_ratio") return f.aspect_ratio;
  return f.von_mises;
}

// Bitwise equality (distinguishes -0.0 from 0.0, which == does not).
inline void expect_same_bits(const std::vector<double>& got, const std::vector<double>& want,
                             const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(std::memcmp(&got[i], &want[i], sizeof(double)), 0)
        << what << "[" << i << "]: " << got[i] << " vs " << want[i];
  }
}

inline constexpr const char* kSpec = R"({"name":"unit","mesh":{"radius_m":0.01}})";

// Writes a whole result: mesh, frames at `times`, history, finish(complete, error).
inline void write_result(const std::string& dir, const Mesh& mesh, const std::vector<double>& times,
                         const History& history, bool complete = true,
                         const std::string& error = "") {
  ResultWriter writer(dir, mesh, kSpec, "0.1.0-test");
  for (std::size_t k = 0; k < times.size(); ++k) {
    writer.write_frame(make_frame(mesh, times[k], static_cast<double>(k)));
  }
  writer.finish(history, make_summary(mesh), complete, error);
}

// ---- the file as a user's tool sees it (plain HDF5 API) ------------------------------------

// Test-side access to the file as a user's tool sees it. Single-threaded, so no lock needed.
struct H5File {
  explicit H5File(const std::string& path) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  }
  ~H5File() {
    if (id >= 0) H5Fclose(id);
  }
  hid_t id = -1;
};

struct DatasetShape {
  H5T_class_t type_class = H5T_NO_CLASS;
  std::size_t type_size = 0;
  std::vector<hsize_t> dims;
  H5D_layout_t layout = H5D_LAYOUT_ERROR;
  std::vector<hsize_t> chunk;
  bool deflate = false, shuffle = false;
  std::string units;
  bool has_units = false;
};

inline std::string string_attr(hid_t obj, const char* name) {
  const hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  if (a < 0) return "<missing>";
  const hid_t t = H5Aget_type(a);
  std::string out = "<not a variable-length string>";
  if (H5Tget_class(t) == H5T_STRING && H5Tis_variable_str(t) > 0) {
    char* p = nullptr;
    const hid_t mt = H5Tcopy(H5T_C_S1);
    H5Tset_size(mt, H5T_VARIABLE);
    H5Tset_cset(mt, H5Tget_cset(t));
    if (H5Aread(a, mt, &p) >= 0 && p) out = p;
    H5free_memory(p);
    H5Tclose(mt);
  }
  H5Tclose(t);
  H5Aclose(a);
  return out;
}

// (class, size in bytes) of an attribute's stored type, e.g. (H5T_INTEGER, 4).
inline std::pair<H5T_class_t, std::size_t> attr_type(hid_t obj, const char* name) {
  const hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  if (a < 0) return {H5T_NO_CLASS, 0};
  const hid_t t = H5Aget_type(a);
  std::pair<H5T_class_t, std::size_t> out{H5Tget_class(t), H5Tget_size(t)};
  H5Tclose(t);
  H5Aclose(a);
  return out;
}

inline DatasetShape shape_of(hid_t file, const std::string& name) {
  DatasetShape s;
  const hid_t ds = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  if (ds < 0) return s;
  const hid_t t = H5Dget_type(ds);
  s.type_class = H5Tget_class(t);
  s.type_size = H5Tget_size(t);
  H5Tclose(t);
  const hid_t space = H5Dget_space(ds);
  s.dims.resize(static_cast<std::size_t>(H5Sget_simple_extent_ndims(space)));
  H5Sget_simple_extent_dims(space, s.dims.data(), nullptr);
  H5Sclose(space);
  const hid_t dcpl = H5Dget_create_plist(ds);
  s.layout = H5Pget_layout(dcpl);
  if (s.layout == H5D_CHUNKED) {
    s.chunk.resize(s.dims.size());
    H5Pget_chunk(dcpl, static_cast<int>(s.chunk.size()), s.chunk.data());
    for (int i = 0; i < H5Pget_nfilters(dcpl); ++i) {
      unsigned flags = 0;
      std::size_t n = 0;
      const H5Z_filter_t f =
          H5Pget_filter2(dcpl, static_cast<unsigned>(i), &flags, &n, nullptr, 0, nullptr, nullptr);
      s.deflate |= f == H5Z_FILTER_DEFLATE;
      s.shuffle |= f == H5Z_FILTER_SHUFFLE;
    }
  }
  H5Pclose(dcpl);
  s.has_units = H5Aexists(ds, "units") > 0;
  if (s.has_units) s.units = string_attr(ds, "units");
  H5Dclose(ds);
  return s;
}

// Every object under the root, as "path" for groups and "path float64 [d0 x d1]" for datasets,
// in name order: the whole layout of a file in one comparable list. (Links and H5Iget_type
// rather than H5Ovisit, whose callback type differs between HDF5 1.10 and 1.12.)
inline std::vector<std::string> list_objects(hid_t file) {
  std::vector<std::string> out;
  const auto visit = [](hid_t root, const char* name, const H5L_info_t*, void* data) -> herr_t {
    std::string entry = name;
    const hid_t obj = H5Oopen(root, name, H5P_DEFAULT);
    if (obj >= 0 && H5Iget_type(obj) == H5I_DATASET) {
      const DatasetShape s = shape_of(root, name);
      entry += std::string(" ") + (s.type_class == H5T_FLOAT ? "float" : "int") +
               std::to_string(8 * s.type_size) + " [";
      for (std::size_t i = 0; i < s.dims.size(); ++i) {
        entry += (i ? " x " : "") + std::to_string(s.dims[i]);
      }
      entry += "]";
    }
    if (obj >= 0) H5Oclose(obj);
    static_cast<std::vector<std::string>*>(data)->push_back(entry);
    return 0;
  };
  H5Lvisit(file, H5_INDEX_NAME, H5_ITER_INC, visit, &out);
  return out;
}

// Names of an object's attributes, in name order.
inline std::vector<std::string> attribute_names(hid_t obj) {
  std::vector<std::string> out;
  const auto visit = [](hid_t, const char* name, const H5A_info_t*, void* data) -> herr_t {
    static_cast<std::vector<std::string>*>(data)->push_back(name);
    return 0;
  };
  H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_INC, nullptr, visit, &out);
  return out;
}

// An integer attribute's value (-1 when absent).
inline int64_t int_attr(hid_t obj, const char* name) {
  int64_t value = -1;
  const hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  if (a < 0) return value;
  H5Aread(a, H5T_NATIVE_INT64, &value);
  H5Aclose(a);
  return value;
}

// A text file's contents (the XDMF companion).
inline std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The whole layout (list_objects) a writer of format_version 2 gives: /fields with `frames`
// groups of the eight fields (node vectors N x 3), /modes, /timeseries, and `mesh`, the /mesh
// entries of the file's dimension. Sorted, as the comparison sorts the file's list.
inline std::vector<std::string> expected_layout(std::size_t n, std::size_t e, std::size_t frames,
                                                std::size_t samples, std::size_t modes,
                                                std::vector<std::string> mesh) {
  const auto dims = [](std::vector<std::size_t> d) {
    std::string s = " [";
    for (std::size_t i = 0; i < d.size(); ++i) s += (i ? " x " : "") + std::to_string(d[i]);
    return s + "]";
  };
  std::vector<std::string> want = {"fields", "mesh", "modes", "timeseries"};
  for (std::size_t k = 0; k < frames; ++k) {
    char group[64];
    std::snprintf(group, sizeof group, "fields/frame_%05zu", k);
    want.push_back(group);
    for (const auto& name : kFieldNames) {
      const bool nodal = name == "displacement" || name == "velocity";
      want.push_back(std::string(group) + "/" + name + " float64" +
                     (nodal ? dims({n, 3}) : dims({e})));
    }
  }
  for (auto& m : mesh) want.push_back("mesh/" + m);
  want.push_back("modes/amplitude float64" + dims({samples, samples ? modes + 1 : 0}));
  want.push_back("modes/time float64" + dims({samples}));
  for (const auto& [name, column] : History{}.columns()) {
    want.push_back("timeseries/" + name + " float64" + dims({samples}));
  }
  std::sort(want.begin(), want.end());
  return want;
}

inline std::vector<std::string> sorted_objects(hid_t file) {
  std::vector<std::string> got = list_objects(file);
  std::sort(got.begin(), got.end());
  return got;
}

// The root attributes of every file of this version, in name order.
inline const std::vector<std::string> kRootAttributes = {
    "complete",       "dimension", "error", "format_version", "frame_count",
    "solver_version", "spec",      "steps", "summary",        "wall_time_s"};

}  // namespace softshock::testing
