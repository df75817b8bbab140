// HDF5 result files, reading: ResultReader, for files of every format_version
// (docs/results-format.md).
#include <fcntl.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string_view>
#include <type_traits>
#include <utility>

#include "solver/io/durable_file.hpp"
#include "solver/io/hdf5_support.hpp"
#include "solver/io/result_file.hpp"

namespace softshock {

using namespace h5;

namespace {

namespace fs = std::filesystem;

// ---- reading helpers (lock held) ------------------------------------------------------------

std::string read_string_attr(hid_t obj, const char* name, const std::string& path) {
  Hid attr = checked(H5Aopen(obj, name, H5P_DEFAULT), std::string("open attribute ") + name, path);
  Hid ftype = checked(H5Aget_type(attr.get()), std::string("get type of attribute ") + name, path);
  if (H5Tget_class(ftype.get()) != H5T_STRING) {
    throw std::runtime_error("HDF5: attribute " + std::string(name) + " is not a string (" + path +
                             ")");
  }
  const htri_t variable = H5Tis_variable_str(ftype.get());
  if (variable < 0) fail(std::string("inspect attribute ") + name, path);
  Hid mtype = checked(H5Tcopy(H5T_C_S1), "create string type", path);
  // HDF5 converts no string between character sets (ASCII/UTF-8): read in the stored one.
  checked(H5Tset_cset(mtype.get(), H5Tget_cset(ftype.get())), "set string charset", path);
  if (variable > 0) {
    checked(H5Tset_size(mtype.get(), H5T_VARIABLE), "set string size", path);
    char* p = nullptr;
    checked(H5Aread(attr.get(), mtype.get(), &p), std::string("read attribute ") + name, path);
    std::string value = p ? p : "";
    H5free_memory(p);
    return value;
  }
  // Fixed-length strings (files written by other tools, e.g. h5py with numpy bytes).
  const std::size_t size = H5Tget_size(ftype.get());
  std::string value(size, '\0');
  checked(H5Tset_size(mtype.get(), size), "set string size", path);
  checked(H5Aread(attr.get(), mtype.get(), value.data()), std::string("read attribute ") + name,
          path);
  value.resize(std::strlen(value.c_str()));
  return value;
}

// A scalar attribute read as T (int64_t or double; HDF5 converts the stored type).
template <typename T>
T read_scalar_attr(hid_t obj, const char* name, const std::string& path) {
  static_assert(std::is_same_v<T, int64_t> || std::is_same_v<T, double>);
  const hid_t memory_type = std::is_same_v<T, double> ? H5T_NATIVE_DOUBLE : H5T_NATIVE_INT64;
  Hid attr = checked(H5Aopen(obj, name, H5P_DEFAULT), std::string("open attribute ") + name, path);
  T value = 0;
  checked(H5Aread(attr.get(), memory_type, &value), std::string("read attribute ") + name, path);
  return value;
}

bool has_attr(hid_t obj, const char* name, const std::string& path) {
  const htri_t exists = H5Aexists(obj, name);
  if (exists < 0) fail(std::string("look up attribute ") + name, path);
  return exists > 0;
}

Hid open_dataset(hid_t file, const std::string& name, const std::string& path) {
  // H5Lexists fails (rather than answering false) when an intermediate group is missing, so
  // test each level: the caller gets "no such dataset" either way.
  std::size_t pos = 0;
  while (true) {
    pos = name.find('/', pos + 1);
    const std::string prefix = name.substr(0, pos);
    if (H5Lexists(file, prefix.c_str(), H5P_DEFAULT) <= 0) {
      H5Eclear2(H5E_DEFAULT);
      throw std::runtime_error("HDF5: no dataset " + name + " in " + path);
    }
    if (pos == std::string::npos) break;
  }
  return checked(H5Dopen2(file, name.c_str(), H5P_DEFAULT), "open dataset " + name, path);
}

// Dimensions of a dataset (rank 1 or 2).
std::vector<hsize_t> dataset_dims(hid_t ds, const std::string& name, const std::string& path) {
  Hid space = checked(H5Dget_space(ds), "get dataspace of " + name, path);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 1 || rank > 2) {
    throw std::runtime_error("HDF5: dataset " + name + " has rank " + std::to_string(rank) +
                             ", expected 1 or 2 (" + path + ")");
  }
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  checked(H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr), "get dims of " + name,
          path);
  return dims;
}

template <typename T>
std::vector<T> read_all(hid_t file, const std::string& name, hid_t mem_type,
                        const std::string& path, std::vector<hsize_t>* dims_out = nullptr) {
  Hid ds = open_dataset(file, name, path);
  const std::vector<hsize_t> dims = dataset_dims(ds.get(), name, path);
  std::size_t count = 1;
  for (hsize_t d : dims) count *= static_cast<std::size_t>(d);
  std::vector<T> values(count);
  if (count > 0) {
    checked(H5Dread(ds.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()),
            "read dataset " + name, path);
  }
  if (dims_out) *dims_out = dims;
  return values;
}

// A dataset that must be rows x `cols` (rank 2): its values, rows in `rows`.
template <typename T>
std::vector<T> read_matrix(hid_t file, const std::string& name, hid_t mem_type, std::size_t cols,
                           const std::string& path, std::size_t& rows) {
  std::vector<hsize_t> dims;
  std::vector<T> values = read_all<T>(file, name, mem_type, path, &dims);
  if (dims.size() != 2 || dims[1] != cols) {
    throw std::runtime_error("HDF5: " + name + " is not a matrix of " + std::to_string(cols) +
                             " columns (" + path + ")");
  }
  rows = static_cast<std::size_t>(dims[0]);
  return values;
}

// Node indices of a 3-D mesh dataset lie in 0..nodes-1: a Mesh with others would send the
// caller's loops out of bounds. (2-D meshes get this check from finalize_mesh.)
void check_node_indices(const std::vector<int32_t>& indices, std::size_t nodes,
                        const std::string& name, const std::string& path) {
  for (std::size_t i = 0; i < indices.size(); ++i) {
    if (indices[i] < 0 || static_cast<std::size_t>(indices[i]) >= nodes) {
      throw std::runtime_error("HDF5: " + name + " entry " + std::to_string(i) + " is node " +
                               std::to_string(indices[i]) + " of " + std::to_string(nodes) + " (" +
                               path + ")");
    }
  }
}

}  // namespace

// ResultReader

struct ResultReader::Impl {
  std::string path;
  Hid file;
  ResultInfo info;
};

ResultReader::ResultReader(const std::string& h5_path) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.path = h5_path;
  std::error_code ec;
  if (!fs::is_regular_file(h5_path, ec)) {
    throw std::runtime_error("result file " + h5_path + " does not exist or is not a file");
  }
  auto lock = lock_hdf5();
  try {
    Hid fapl = file_access_plist(h5_path);
    m.file = checked(H5Fopen(h5_path.c_str(), H5F_ACC_RDONLY, fapl.get()), "open file", h5_path);
    const hid_t root = m.file.get();
    const int64_t version = read_scalar_attr<int64_t>(root, "format_version", h5_path);
    if (version < 1 || version > kFormatVersion) {
      throw std::runtime_error("result file " + h5_path + " has format_version " +
                               std::to_string(version) + "; this reader knows 1.." +
                               std::to_string(kFormatVersion));
    }
    ResultInfo& info = m.info;
    info.complete = read_scalar_attr<int64_t>(root, "complete", h5_path) != 0;
    info.error = read_string_attr(root, "error", h5_path);
    info.spec_json = read_string_attr(root, "spec", h5_path);
    info.summary_json = read_string_attr(root, "summary", h5_path);
    info.solver_version = read_string_attr(root, "solver_version", h5_path);
    // Files written before 3-D results have no `dimension`: they are all 2-D.
    const int64_t dimension = has_attr(root, "dimension", h5_path)
                                  ? read_scalar_attr<int64_t>(root, "dimension", h5_path)
                                  : 2;
    if (dimension != 2 && dimension != 3) {
      throw std::runtime_error("result file " + h5_path + " has dimension " +
                               std::to_string(dimension) + ", expected 2 or 3");
    }
    info.dimension = static_cast<int>(dimension);
    {
      Hid ds = open_dataset(root, "/mesh/nodes", h5_path);
      info.nodes = dataset_dims(ds.get(), "/mesh/nodes", h5_path)[0];
    }
    {
      const char* elements = info.dimension == 3 ? "/mesh/tetrahedra" : "/mesh/triangles";
      Hid ds = open_dataset(root, elements, h5_path);
      info.elements = dataset_dims(ds.get(), elements, h5_path)[0];
    }
    // Frames are frame_00000 .. frame_{K-1}: count the links rather than trust frame_count.
    Hid fields = checked(H5Gopen2(root, "fields", H5P_DEFAULT), "open group /fields", h5_path);
    H5G_info_t ginfo{};
    checked(H5Gget_info(fields.get(), &ginfo), "get info of /fields", h5_path);
    for (hsize_t k = 0; k < ginfo.nlinks; ++k) {
      const std::string name = frame_group_name(static_cast<std::size_t>(k));
      Hid g =
          checked(H5Gopen2(fields.get(), name.c_str(), H5P_DEFAULT), "open group " + name, h5_path);
      info.frame_times.push_back(read_scalar_attr<double>(g.get(), "time", h5_path));
    }
  } catch (...) {
    m.file.reset();
    throw;
  }
}

ResultReader::~ResultReader() {
  if (!impl_) return;
  auto lock = lock_hdf5();
  impl_->file.reset();
}

const ResultInfo& ResultReader::info() const {
  return impl_->info;
}

Mesh ResultReader::mesh() const {
  if (impl_->info.dimension == 3) return mesh_3d();
  Mesh mesh;
  const std::string& path = impl_->path;
  {
    auto lock = lock_hdf5();
    const hid_t f = impl_->file.get();
    std::vector<hsize_t> dims;
    const auto xy = read_all<double>(f, "/mesh/nodes", H5T_NATIVE_DOUBLE, path, &dims);
    if (dims.size() != 2 || dims[1] != 2) {
      throw std::runtime_error("HDF5: /mesh/nodes is not N x 2 (" + path + ")");
    }
    const std::size_t n = dims[0];
    mesh.x.resize(n);
    mesh.y.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      mesh.x[i] = xy[2 * i];
      mesh.y[i] = xy[2 * i + 1];
    }
    const auto tri = read_all<int32_t>(f, "/mesh/triangles", H5T_NATIVE_INT32, path, &dims);
    if (dims.size() != 2 || dims[1] != 3) {
      throw std::runtime_error("HDF5: /mesh/triangles is not E x 3 (" + path + ")");
    }
    mesh.triangles.resize(dims[0]);
    for (std::size_t e = 0; e < mesh.triangles.size(); ++e) {
      mesh.triangles[e] = {tri[3 * e], tri[3 * e + 1], tri[3 * e + 2]};
    }
    mesh.boundary_nodes = read_all<int32_t>(f, "/mesh/boundary_nodes", H5T_NATIVE_INT32, path);
  }
  // finalize_mesh rebuilds boundary_edges (and validates the mesh). It also recomputes the outer
  // loop, whose starting node may differ: the stored loop is the record, so keep it.
  std::vector<int32_t> stored_loop = std::move(mesh.boundary_nodes);
  finalize_mesh(mesh);
  mesh.boundary_nodes = std::move(stored_loop);
  return mesh;
}

// The stored record as it is: finalize_mesh's 3-D half would re-orient and re-derive what the
// writer stored from a mesh already finalized, and this reader must not depend on it. The checks
// are those a caller's loops rely on: shapes, finite coordinates, node indices in range.
Mesh ResultReader::mesh_3d() const {
  Mesh mesh;
  const std::string& path = impl_->path;
  std::size_t n = 0, e = 0, faces = 0;
  std::vector<double> xyz;
  std::vector<int32_t> tets, boundary;
  {
    auto lock = lock_hdf5();
    const hid_t f = impl_->file.get();
    xyz = read_matrix<double>(f, "/mesh/nodes", H5T_NATIVE_DOUBLE, 3, path, n);
    tets = read_matrix<int32_t>(f, "/mesh/tetrahedra", H5T_NATIVE_INT32, 4, path, e);
    boundary = read_matrix<int32_t>(f, "/mesh/boundary_faces", H5T_NATIVE_INT32, 3, path, faces);
  }
  for (std::size_t i = 0; i < xyz.size(); ++i) {
    if (!std::isfinite(xyz[i])) {
      throw std::runtime_error("HDF5: /mesh/nodes has a non-finite coordinate at node " +
                               std::to_string(i / 3) + " (" + path + ")");
    }
  }
  check_node_indices(tets, n, "/mesh/tetrahedra", path);
  check_node_indices(boundary, n, "/mesh/boundary_faces", path);
  mesh.x.resize(n);
  mesh.y.resize(n);
  mesh.z.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    mesh.x[i] = xyz[3 * i];
    mesh.y[i] = xyz[3 * i + 1];
    mesh.z[i] = xyz[3 * i + 2];
  }
  mesh.tetrahedra.resize(e);
  for (std::size_t k = 0; k < e; ++k) {
    mesh.tetrahedra[k] = {tets[4 * k], tets[4 * k + 1], tets[4 * k + 2], tets[4 * k + 3]};
  }
  mesh.boundary_faces.resize(faces);
  for (std::size_t k = 0; k < faces; ++k) {
    mesh.boundary_faces[k] = {boundary[3 * k], boundary[3 * k + 1], boundary[3 * k + 2]};
  }
  return mesh;
}

std::vector<double> ResultReader::series(const std::string& name) const {
  if (name.empty() || name.find('/') != std::string::npos || name == "." || name == "..") {
    throw std::invalid_argument("ResultReader::series: bad series name '" + name + "'");
  }
  auto lock = lock_hdf5();
  return read_all<double>(impl_->file.get(), "/timeseries/" + name, H5T_NATIVE_DOUBLE, impl_->path);
}

std::vector<std::string> ResultReader::series_names() const {
  auto lock = lock_hdf5();
  const std::string& path = impl_->path;
  Hid g = checked(H5Gopen2(impl_->file.get(), "timeseries", H5P_DEFAULT), "open group /timeseries",
                  path);
  H5G_info_t ginfo{};
  checked(H5Gget_info(g.get(), &ginfo), "get info of /timeseries", path);
  // Creation order is History::columns() order; files without that index fall back to names.
  Hid gcpl = checked(H5Gget_create_plist(g.get()), "get group creation list", path);
  unsigned order_flags = 0;
  checked(H5Pget_link_creation_order(gcpl.get(), &order_flags), "get link order", path);
  const H5_index_t index =
      (order_flags & H5P_CRT_ORDER_INDEXED) ? H5_INDEX_CRT_ORDER : H5_INDEX_NAME;
  std::vector<std::string> names;
  for (hsize_t k = 0; k < ginfo.nlinks; ++k) {
    const ssize_t len =
        H5Lget_name_by_idx(g.get(), ".", index, H5_ITER_INC, k, nullptr, 0, H5P_DEFAULT);
    if (len < 0) fail("get link name in /timeseries", path);
    std::string name(static_cast<std::size_t>(len) + 1, '\0');
    if (H5Lget_name_by_idx(g.get(), ".", index, H5_ITER_INC, k, name.data(), name.size(),
                           H5P_DEFAULT) < 0) {
      fail("get link name in /timeseries", path);
    }
    name.resize(static_cast<std::size_t>(len));
    names.push_back(std::move(name));
  }
  return names;
}

std::vector<double> ResultReader::mode_times() const {
  auto lock = lock_hdf5();
  return read_all<double>(impl_->file.get(), "/modes/time", H5T_NATIVE_DOUBLE, impl_->path);
}

std::vector<double> ResultReader::mode_amplitudes(std::size_t& rows, std::size_t& cols) const {
  auto lock = lock_hdf5();
  std::vector<hsize_t> dims;
  auto values = read_all<double>(impl_->file.get(), "/modes/amplitude", H5T_NATIVE_DOUBLE,
                                 impl_->path, &dims);
  rows = dims[0];
  cols = dims.size() > 1 ? dims[1] : 1;
  return values;
}

std::vector<std::size_t> ResultReader::dims(const std::string& dataset) const {
  auto lock = lock_hdf5();
  Hid ds = open_dataset(impl_->file.get(), dataset, impl_->path);
  const auto d = dataset_dims(ds.get(), dataset, impl_->path);
  return {d.begin(), d.end()};
}

std::vector<double> ResultReader::slice(const std::string& dataset, const Slice& s) const {
  auto lock = lock_hdf5();
  const std::string& path = impl_->path;
  Hid ds = open_dataset(impl_->file.get(), dataset, path);
  const std::vector<hsize_t> d = dataset_dims(ds.get(), dataset, path);
  const hsize_t cols = d.size() > 1 ? d[1] : 1;
  const bool inside =
      s.stride >= 1 && s.col_count >= 1 && s.col_first + s.col_count <= cols &&
      (s.rows == 0 || (s.first < d[0] && (s.rows - 1) <= (d[0] - 1 - s.first) / s.stride));
  if (!inside) throw std::runtime_error("HDF5: slice outside " + dataset + " (" + path + ")");
  std::vector<double> values(s.rows * s.col_count);
  if (values.empty()) return values;
  Hid file_space = checked(H5Dget_space(ds.get()), "get dataspace of " + dataset, path);
  const hsize_t start[2] = {s.first, s.col_first}, stride[2] = {s.stride, 1};
  const hsize_t count[2] = {s.rows, s.col_count};
  checked(H5Sselect_hyperslab(file_space.get(), H5S_SELECT_SET, start, stride, count, nullptr),
          "select in " + dataset, path);
  const hsize_t memory_dims[1] = {values.size()};
  Hid memory_space = checked(H5Screate_simple(1, memory_dims, nullptr), "create dataspace", path);
  checked(H5Dread(ds.get(), H5T_NATIVE_DOUBLE, memory_space.get(), file_space.get(), H5P_DEFAULT,
                  values.data()),
          "read dataset " + dataset, path);
  return values;
}

std::vector<double> ResultReader::field(std::size_t frame, const std::string& name) const {
  const auto known = std::find_if(kFields.begin(), kFields.end(),
                                  [&](const FieldSpec& f) { return name == f.name; });
  const bool damage = name == kDamageField.name;  // N values (a run with damage only)
  if (known == kFields.end() && !damage) {
    throw std::invalid_argument("ResultReader::field: unknown field '" + name + "'");
  }
  if (frame >= impl_->info.frame_times.size()) {
    throw std::out_of_range("ResultReader::field: frame " + std::to_string(frame) + " of " +
                            std::to_string(impl_->info.frame_times.size()) + " in " + impl_->path);
  }
  auto lock = lock_hdf5();
  std::vector<hsize_t> dims;
  const std::string dataset = "/fields/" + frame_group_name(frame) + "/" + name;
  std::vector<double> v =
      read_all<double>(impl_->file.get(), dataset, H5T_NATIVE_DOUBLE, impl_->path, &dims);
  if (damage || !known->nodal) return v;
  const std::size_t cols = dims.size() == 2 ? static_cast<std::size_t>(dims[1]) : 0;
  if (impl_->info.dimension == 3) {  // N x 3 on disk and in memory: the z column is data
    if (cols != kVectorColumns) {
      throw std::runtime_error("HDF5: " + dataset + " is not N x 3 (" + impl_->path + ")");
    }
    return v;
  }
  // 2-D callers get (x, y) pairs from either version: N x 2 (version 1) or N x 3 (z dropped).
  if (cols != 2 && cols != kVectorColumns) {
    throw std::runtime_error("HDF5: " + dataset + " is not N x 2 or N x 3 (" + impl_->path + ")");
  }
  const std::size_t n = static_cast<std::size_t>(dims[0]);
  for (std::size_t i = 0; cols == kVectorColumns && i < n; ++i) {
    v[2 * i] = v[kVectorColumns * i];
    v[2 * i + 1] = v[kVectorColumns * i + 1];
  }
  v.resize(2 * n);
  return v;
}

}  // namespace softshock
