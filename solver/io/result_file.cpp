// HDF5 result files: ResultWriter (temporary file, then flush + fsync + rename) and
// ResultReader. The layout is a contract with users: docs/results-format.md describes it, and a
// change here needs a change there (and a new format_version when it is not an addition).
#include "solver/io/result_file.hpp"

#include <fcntl.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "solver/io/durable_file.hpp"

namespace softshock {

namespace detail {
// xdmf.cpp (private to this module, hence no header).
std::string xdmf_document(const std::string& h5_file, std::size_t nodes, std::size_t elements,
                          const std::vector<std::string>& frame_groups,
                          const std::vector<double>& frame_times,
                          const std::vector<std::pair<std::string, bool>>& attributes);
}  // namespace detail

namespace {

namespace fs = std::filesystem;

// 2: node vectors are N x 3 (z = 0), so ParaView's default XDMF reader offers Warp By Vector.
// Version 1 files (N x 2) are still read.
constexpr int kFormatVersion = 2;
constexpr std::size_t kVectorColumns = 3;
constexpr const char* kH5Name = "result.h5";
constexpr const char* kXdmfName = "result.xdmf";

// Storage policy (see docs/results-format.md for the measurements). Floating-point datasets
// (fields, series, modes, coordinates) are contiguous and uncompressed: solver output carries
// full-precision noise in its low bytes, so shuffle + deflate kept 0.78-0.87 of their size at
// ~20x the CPU of writing them raw (a quarter of a grid point's CPU, for 18 % of its disk).
// Integer datasets (connectivity) shrink to ~0.27 and are compressed: above kMinChunkedBytes,
// chunks of whole rows of about kTargetChunkBytes (inside the 10 KiB - 1 MiB range where HDF5's
// chunk cache and index behave well), byte shuffle then deflate at the cheapest level (levels
// 1-4 gave sizes within 0.5 %; every write holds the process-wide HDF5 lock). Below
// kMinChunkedBytes compression would save a few KiB at the price of a chunk index.
constexpr std::size_t kMinChunkedBytes = 16 * 1024;
constexpr std::size_t kTargetChunkBytes = 256 * 1024;
constexpr unsigned kDeflateLevel = 1;

// The per-frame fields: dataset name, node-centred (N x 2 in memory, N x 3 on disk) or per
// element (E), member, units.
struct FieldSpec {
  const char* name;
  bool nodal;
  std::vector<double> FieldFrame::*member;
  const char* units;
};
constexpr std::array<FieldSpec, 8> kFields{{
    {"displacement", true, &FieldFrame::displacement, "m"},
    {"velocity", true, &FieldFrame::velocity, "m/s"},
    {"J", false, &FieldFrame::J, "1"},
    {"mean_stress", false, &FieldFrame::mean_stress, "Pa"},
    {"radial_stress", false, &FieldFrame::radial_stress, "Pa"},
    {"hoop_stress", false, &FieldFrame::hoop_stress, "Pa"},
    {"von_mises", false, &FieldFrame::von_mises, "Pa"},
    {"aspect_ratio", false, &FieldFrame::aspect_ratio, "1"},
}};

std::string frame_group_name(std::size_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%05zu", k);
  return buf;
}

// ---- the process-wide HDF5 lock ----------------------------------------------------------

// libhdf5 keeps global state (identifier tables, caches, free lists) shared by all files and
// is safe for threads only when built with --enable-threadsafe. Debian 12's build is, but other
// builds (a self-built or vendored HDF5) are not, so every HDF5 call of this module goes through
// one process-wide mutex whatever the build. Handles are closed under it too: declare the lock
// before any Hid in a scope so it is released last.
std::unique_lock<std::mutex> lock_hdf5() {
  static std::mutex mutex;
  std::unique_lock<std::mutex> lock(mutex);
  // Errors become exceptions with the library's own message (see fail()); the default handler
  // would also print the whole stack to stderr, into the daemon's log. Set on every lock because
  // a thread-safe libhdf5 keeps this setting per thread.
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  return lock;
}

// The innermost (most specific) description on HDF5's error stack, e.g. "unable to open file:
// name = '...', errno = 2, error message = 'No such file or directory'". Clears the stack.
std::string hdf5_error_detail() {
  std::string detail;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_UPWARD,
      [](unsigned n, const H5E_error2_t* err, void* data) -> herr_t {
        if (n == 0 && err->desc) *static_cast<std::string*>(data) = err->desc;
        return 0;
      },
      &detail);
  H5Eclear2(H5E_DEFAULT);
  return detail;
}

[[noreturn]] void fail(const std::string& what, const std::string& path) {
  const std::string detail = hdf5_error_detail();
  throw std::runtime_error("HDF5: " + what + " (" + path + ")" +
                           (detail.empty() ? "" : ": " + detail));
}

// Owner of one HDF5 identifier. Must be destroyed with the HDF5 lock held.
class Hid {
 public:
  Hid() = default;
  explicit Hid(hid_t id) : id_(id) {}
  Hid(Hid&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)) {}
  Hid& operator=(Hid&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
    }
    return *this;
  }
  Hid(const Hid&) = delete;
  Hid& operator=(const Hid&) = delete;
  ~Hid() { reset(); }

  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  // Gives up ownership (for closes whose status matters, e.g. H5Fclose).
  hid_t release() { return std::exchange(id_, H5I_INVALID_HID); }
  // H5Idec_ref closes any kind of identifier (file, group, dataset, type, space, plist).
  void reset() {
    if (id_ >= 0) H5Idec_ref(id_);
    id_ = H5I_INVALID_HID;
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
};

Hid checked(hid_t id, const std::string& what, const std::string& path) {
  if (id < 0) fail(what, path);
  return Hid(id);
}
void checked(herr_t rc, const std::string& what, const std::string& path) {
  if (rc < 0) fail(what, path);
}

// ---- writing helpers (lock held) ------------------------------------------------------------

// Creation properties shared by groups and datasets: no access/modification timestamps in the
// object headers, so the same run written twice gives byte-identical files.
Hid object_plist(hid_t cls, const std::string& path) {
  Hid pl = checked(H5Pcreate(cls), "create property list", path);
  checked(H5Pset_obj_track_times(pl.get(), 0), "set object timestamps", path);
  return pl;
}

Hid create_group(hid_t loc, const char* name, const std::string& path, bool track_order) {
  Hid gcpl = object_plist(H5P_GROUP_CREATE, path);
  if (track_order) {
    // Readers list /timeseries in History::columns() order ("time" first), not alphabetically.
    checked(H5Pset_link_creation_order(gcpl.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED),
            "set link creation order", path);
  }
  return checked(H5Gcreate2(loc, name, H5P_DEFAULT, gcpl.get(), H5P_DEFAULT),
                 std::string("create group ") + name, path);
}

bool deflate_available() {
  // Queried once, under the lock (the first call is always made by a writer holding it).
  static const bool available = H5Zfilter_avail(H5Z_FILTER_DEFLATE) > 0;
  return available;
}

// Shape of a dataset: a vector (rank 1) or a row-major rows x cols matrix (rank 2).
struct Shape {
  int rank;
  std::size_t rows, cols;  // cols is 1 for a vector
};
Shape vector_shape(std::size_t n) {
  return {1, n, 1};
}
Shape matrix_shape(std::size_t rows, std::size_t cols) {
  return {2, rows, cols};
}

// Creates and writes a dataset of file type `file_type` from `data` in memory type `mem_type`,
// with the storage policy above, and its `units` attribute when units is not null.
enum class Compression { kNone, kShuffleDeflate };
void write_dataset(hid_t loc, const char* name, hid_t file_type, hid_t mem_type,
                   std::size_t element_bytes, Shape shape, const void* data, const char* units,
                   Compression compression, const std::string& path) {
  const std::array<hsize_t, 2> dims{shape.rows, shape.cols};
  Hid space = checked(H5Screate_simple(shape.rank, dims.data(), nullptr), "create dataspace", path);
  Hid dcpl = object_plist(H5P_DATASET_CREATE, path);
  const std::size_t row_bytes = element_bytes * shape.cols;
  if (compression == Compression::kShuffleDeflate && shape.rows * row_bytes >= kMinChunkedBytes &&
      deflate_available()) {
    const std::size_t chunk_rows =
        std::clamp<std::size_t>(kTargetChunkBytes / row_bytes, 1, shape.rows);
    const std::array<hsize_t, 2> chunk{chunk_rows, shape.cols};
    checked(H5Pset_chunk(dcpl.get(), shape.rank, chunk.data()), "set chunking", path);
    checked(H5Pset_shuffle(dcpl.get()), "set shuffle filter", path);
    checked(H5Pset_deflate(dcpl.get(), kDeflateLevel), "set deflate filter", path);
  }
  Hid ds =
      checked(H5Dcreate2(loc, name, file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
              std::string("create dataset ") + name, path);
  if (shape.rows * shape.cols > 0) {
    checked(H5Dwrite(ds.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data),
            std::string("write dataset ") + name, path);
  }
  if (units) {
    Hid st = checked(H5Tcopy(H5T_C_S1), "create string type", path);
    checked(H5Tset_size(st.get(), H5T_VARIABLE), "set string size", path);
    checked(H5Tset_cset(st.get(), H5T_CSET_UTF8), "set string charset", path);
    Hid scalar = checked(H5Screate(H5S_SCALAR), "create dataspace", path);
    Hid attr =
        checked(H5Acreate2(ds.get(), "units", st.get(), scalar.get(), H5P_DEFAULT, H5P_DEFAULT),
                std::string("create attribute units of ") + name, path);
    checked(H5Awrite(attr.get(), st.get(), &units), std::string("write units of ") + name, path);
  }
}

void write_doubles(hid_t loc, const char* name, const double* data, Shape shape, const char* units,
                   const std::string& path) {
  write_dataset(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, sizeof(double), shape, data, units,
                Compression::kNone, path);
}

void write_int32s(hid_t loc, const char* name, const int32_t* data, Shape shape,
                  const std::string& path) {
  write_dataset(loc, name, H5T_STD_I32LE, H5T_NATIVE_INT32, sizeof(int32_t), shape, data, nullptr,
                Compression::kShuffleDeflate, path);
}

// Scalar attribute, replacing an existing one of the same name (the root attributes are first
// written when the file is created, so a temporary file already reads as incomplete).
Hid recreate_attribute(hid_t obj, const char* name, hid_t type, const std::string& path) {
  const htri_t exists = H5Aexists(obj, name);
  if (exists < 0) fail(std::string("look up attribute ") + name, path);
  if (exists > 0) checked(H5Adelete(obj, name), std::string("delete attribute ") + name, path);
  Hid scalar = checked(H5Screate(H5S_SCALAR), "create dataspace", path);
  return checked(H5Acreate2(obj, name, type, scalar.get(), H5P_DEFAULT, H5P_DEFAULT),
                 std::string("create attribute ") + name, path);
}

// Strings are variable-length UTF-8: h5py returns them as str, and they live in the global
// heap, so a large spec or summary JSON does not hit the 64 KiB object-header limit.
void write_string_attr(hid_t obj, const char* name, const std::string& value,
                       const std::string& path) {
  Hid st = checked(H5Tcopy(H5T_C_S1), "create string type", path);
  checked(H5Tset_size(st.get(), H5T_VARIABLE), "set string size", path);
  checked(H5Tset_cset(st.get(), H5T_CSET_UTF8), "set string charset", path);
  Hid attr = recreate_attribute(obj, name, st.get(), path);
  const char* p = value.c_str();
  checked(H5Awrite(attr.get(), st.get(), &p), std::string("write attribute ") + name, path);
}

void write_int_attr(hid_t obj, const char* name, int64_t value, hid_t file_type,
                    const std::string& path) {
  Hid attr = recreate_attribute(obj, name, file_type, path);
  checked(H5Awrite(attr.get(), H5T_NATIVE_INT64, &value), std::string("write attribute ") + name,
          path);
}

void write_double_attr(hid_t obj, const char* name, double value, const std::string& path) {
  Hid attr = recreate_attribute(obj, name, H5T_IEEE_F64LE, path);
  checked(H5Awrite(attr.get(), H5T_NATIVE_DOUBLE, &value), std::string("write attribute ") + name,
          path);
}

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

int64_t read_int_attr(hid_t obj, const char* name, const std::string& path) {
  Hid attr = checked(H5Aopen(obj, name, H5P_DEFAULT), std::string("open attribute ") + name, path);
  int64_t value = 0;
  checked(H5Aread(attr.get(), H5T_NATIVE_INT64, &value), std::string("read attribute ") + name,
          path);
  return value;
}

double read_double_attr(hid_t obj, const char* name, const std::string& path) {
  Hid attr = checked(H5Aopen(obj, name, H5P_DEFAULT), std::string("open attribute ") + name, path);
  double value = 0;
  checked(H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &value), std::string("read attribute ") + name,
          path);
  return value;
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

// File access properties: close everything still open with the file (so H5Fclose really
// releases it before the fsync and rename), and use file locks where the filesystem has them
// without failing where it has none (NFS without lockd).
Hid file_access_plist(const std::string& path) {
  Hid fapl = checked(H5Pcreate(H5P_FILE_ACCESS), "create file access list", path);
  checked(H5Pset_fclose_degree(fapl.get(), H5F_CLOSE_STRONG), "set close degree", path);
  checked(H5Pset_file_locking(fapl.get(), 1, 1), "set file locking", path);
  return fapl;
}

}  // namespace

std::string link_result_files(const std::string& source_h5, const std::string& out_dir) {
  const fs::path src(source_h5);
  const fs::path dir(out_dir);
  fs::create_directories(dir);
  for (const char* ext : {".h5", ".xdmf"}) {
    const fs::path from = fs::path(src).replace_extension(ext);
    const fs::path to = dir / (std::string("result") + ext);
    std::error_code ec;
    if (!fs::exists(from, ec)) {
      if (std::string(ext) == ".h5") throw std::runtime_error("no result file " + from.string());
      continue;  // the XDMF companion is a convenience
    }
    fs::remove(to, ec);
    fs::create_hard_link(from, to, ec);
    if (ec) fs::copy_file(from, to, fs::copy_options::overwrite_existing);
    fsync_path(to, false);
  }
  fsync_path(dir, true);
  return (dir / "result.h5").string();
}

// =================================================================================================
// ResultWriter

struct ResultWriter::Impl {
  fs::path dir, tmp_h5, final_h5, tmp_xdmf, final_xdmf;
  std::string tmp_name;  // tmp_h5 as a string, for messages
  std::size_t nodes = 0, elements = 0;
  Hid file, fields;  // open from construction until finish() closes them
  std::vector<std::string> frame_groups;
  std::vector<double> frame_times;
  std::vector<double> xyz;  // a node vector padded with z = 0, reused across frames
  bool finished = false;
  std::string broken;  // set when an operation failed half-way: the file is not to be trusted

  void check_usable(const char* op) const {
    if (finished) throw std::logic_error(std::string("ResultWriter::") + op + " after finish()");
    if (!broken.empty()) {
      throw std::runtime_error("result file " + tmp_name +
                               " unusable after an earlier error: " + broken);
    }
  }
};

ResultWriter::ResultWriter(const std::string& out_dir, const Mesh& mesh,
                           const std::string& spec_json, const std::string& solver_version)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  if (mesh.x.size() != mesh.y.size()) {
    throw std::invalid_argument("ResultWriter: mesh has " + std::to_string(mesh.x.size()) +
                                " x but " + std::to_string(mesh.y.size()) + " y coordinates");
  }
  m.dir = fs::path(out_dir);
  std::error_code ec;
  fs::create_directories(m.dir, ec);
  if (ec)
    throw std::runtime_error("cannot create result directory " + out_dir + ": " + ec.message());
  m.final_h5 = m.dir / kH5Name;
  m.tmp_h5 = m.dir / (std::string(kH5Name) + ".tmp");
  m.final_xdmf = m.dir / kXdmfName;
  m.tmp_xdmf = m.dir / (std::string(kXdmfName) + ".tmp");
  m.tmp_name = m.tmp_h5.string();
  m.nodes = mesh.node_count();
  m.elements = mesh.element_count();

  const std::string& path = m.tmp_name;
  auto lock = lock_hdf5();
  try {
    Hid fapl = file_access_plist(path);
    // H5F_ACC_TRUNC: a .tmp left by a crashed earlier attempt is simply overwritten.
    m.file = checked(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()), "create file",
                     path);
    const hid_t root = m.file.get();
    write_string_attr(root, "spec", spec_json, path);
    write_string_attr(root, "solver_version", solver_version, path);
    write_int_attr(root, "format_version", kFormatVersion, H5T_STD_I32LE, path);
    write_int_attr(root, "complete", 0, H5T_STD_I32LE, path);
    write_string_attr(root, "error", "", path);

    Hid g = create_group(root, "mesh", path, false);
    std::vector<double> xy(2 * m.nodes);
    for (std::size_t i = 0; i < m.nodes; ++i) {
      xy[2 * i] = mesh.x[i];
      xy[2 * i + 1] = mesh.y[i];
    }
    write_doubles(g.get(), "nodes", xy.data(), matrix_shape(m.nodes, 2), "m", path);
    static_assert(sizeof(std::array<int32_t, 3>) == 3 * sizeof(int32_t));
    write_int32s(g.get(), "triangles", reinterpret_cast<const int32_t*>(mesh.triangles.data()),
                 matrix_shape(m.elements, 3), path);
    write_int32s(g.get(), "boundary_nodes", mesh.boundary_nodes.data(),
                 vector_shape(mesh.boundary_nodes.size()), path);
    m.fields = create_group(root, "fields", path, false);
  } catch (...) {
    // Construction failed: nothing of this run may stay behind.
    m.fields.reset();
    m.file.reset();
    std::error_code ignored;
    fs::remove(m.tmp_h5, ignored);
    throw;
  }
}

ResultWriter::~ResultWriter() {
  if (!impl_) return;
  Impl& m = *impl_;
  {
    auto lock = lock_hdf5();
    m.fields.reset();
    m.file.reset();
  }
  if (!m.finished) {
    std::error_code ignored;
    fs::remove(m.tmp_h5, ignored);
    fs::remove(m.tmp_xdmf, ignored);
  }
}

void ResultWriter::write_frame(const FieldFrame& frame) {
  Impl& m = *impl_;
  m.check_usable("write_frame");
  for (const FieldSpec& f : kFields) {
    const std::size_t expected = f.nodal ? 2 * m.nodes : m.elements;
    const std::size_t got = (frame.*f.member).size();
    if (got != expected) {
      throw std::invalid_argument("ResultWriter::write_frame: field " + std::string(f.name) +
                                  " has " + std::to_string(got) + " values, expected " +
                                  std::to_string(expected));
    }
  }
  const std::string name = frame_group_name(m.frame_groups.size());
  const std::string& path = m.tmp_name;
  auto lock = lock_hdf5();
  try {
    Hid g = create_group(m.fields.get(), name.c_str(), path, false);
    write_double_attr(g.get(), "time", frame.time_s, path);
    for (const FieldSpec& f : kFields) {
      const std::vector<double>& v = frame.*f.member;
      if (!f.nodal) {
        write_doubles(g.get(), f.name, v.data(), vector_shape(m.elements), f.units, path);
        continue;
      }
      m.xyz.assign(kVectorColumns * m.nodes, 0.0);
      for (std::size_t i = 0; i < m.nodes; ++i) {
        m.xyz[kVectorColumns * i] = v[2 * i];
        m.xyz[kVectorColumns * i + 1] = v[2 * i + 1];
      }
      write_doubles(g.get(), f.name, m.xyz.data(), matrix_shape(m.nodes, kVectorColumns), f.units,
                    path);
    }
  } catch (const std::exception& e) {
    m.broken = e.what();
    throw;
  }
  m.frame_groups.push_back("/fields/" + name);
  m.frame_times.push_back(frame.time_s);
}

void ResultWriter::finish(const History& history, const RunSummary& summary, bool complete,
                          const std::string& error) {
  Impl& m = *impl_;
  m.check_usable("finish");
  // Validate before touching the file: a bad History leaves the writer usable for a retry.
  const auto columns = history.columns();
  const std::size_t samples = history.size();
  for (const auto& [name, column] : columns) {
    if (column->size() != samples) {
      throw std::invalid_argument("ResultWriter::finish: series " + name + " has " +
                                  std::to_string(column->size()) + " samples, time has " +
                                  std::to_string(samples));
    }
  }
  if (!history.modes.empty() && history.modes.size() != samples) {
    throw std::invalid_argument("ResultWriter::finish: " + std::to_string(history.modes.size()) +
                                " mode samples for " + std::to_string(samples) + " time samples");
  }
  const std::size_t mode_cols = history.modes.empty() ? 0 : history.modes.front().size();
  std::vector<double> amplitudes;
  amplitudes.reserve(history.modes.size() * mode_cols);
  for (const auto& row : history.modes) {
    if (row.size() != mode_cols) {
      throw std::invalid_argument("ResultWriter::finish: mode samples differ in length");
    }
    amplitudes.insert(amplitudes.end(), row.begin(), row.end());
  }
  const std::string summary_json = summary_to_json(summary);

  const std::string& path = m.tmp_name;
  try {
    {
      auto lock = lock_hdf5();
      const hid_t root = m.file.get();
      Hid ts = create_group(root, "timeseries", path, true);
      for (const auto& [name, column] : columns) {
        const std::string units = series_units(name);
        write_doubles(ts.get(), name.c_str(), column->data(), vector_shape(column->size()),
                      units.c_str(), path);
      }
      Hid modes = create_group(root, "modes", path, false);
      const std::size_t mode_rows = history.modes.size();
      write_doubles(modes.get(), "time", history.time.data(), vector_shape(mode_rows), "s", path);
      write_doubles(modes.get(), "amplitude", amplitudes.data(), matrix_shape(mode_rows, mode_cols),
                    "1", path);

      write_string_attr(root, "summary", summary_json, path);
      write_int_attr(root, "steps", summary.steps, H5T_STD_I64LE, path);
      write_double_attr(root, "wall_time_s", summary.wall_time_s, path);
      write_int_attr(root, "frame_count", static_cast<int64_t>(m.frame_groups.size()),
                     H5T_STD_I64LE, path);
      write_string_attr(root, "error", error, path);
      write_int_attr(root, "complete", complete ? 1 : 0, H5T_STD_I32LE, path);

      ts.reset();
      modes.reset();
      m.fields.reset();
      checked(H5Fflush(root, H5F_SCOPE_GLOBAL), "flush file", path);
      // H5Fclose rather than the generic close: its status reports the final metadata writes.
      // The identifier is gone whether or not it succeeded.
      if (H5Fclose(m.file.release()) < 0) fail("close file", path);
    }
    // Data on disk before the name: after a crash result.h5 is either absent or whole.
    fsync_path(m.tmp_h5, false);
    std::vector<std::pair<std::string, bool>> attributes;
    for (const FieldSpec& f : kFields) attributes.emplace_back(f.name, f.nodal);
    write_file_synced(m.tmp_xdmf, detail::xdmf_document(kH5Name, m.nodes, m.elements,
                                                        m.frame_groups, m.frame_times, attributes));
    rename_file(m.tmp_h5, m.final_h5);
    rename_file(m.tmp_xdmf, m.final_xdmf);
    fsync_path(m.dir, true);
  } catch (const std::exception& e) {
    m.broken = e.what();
    throw;
  }
  m.finished = true;
}

std::string ResultWriter::h5_path() const {
  return impl_->final_h5.string();
}
std::string ResultWriter::xdmf_path() const {
  return impl_->final_xdmf.string();
}

// =================================================================================================
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
    const int64_t version = read_int_attr(root, "format_version", h5_path);
    if (version < 1 || version > kFormatVersion) {
      throw std::runtime_error("result file " + h5_path + " has format_version " +
                               std::to_string(version) + "; this reader knows 1.." +
                               std::to_string(kFormatVersion));
    }
    ResultInfo& info = m.info;
    info.complete = read_int_attr(root, "complete", h5_path) != 0;
    info.error = read_string_attr(root, "error", h5_path);
    info.spec_json = read_string_attr(root, "spec", h5_path);
    info.summary_json = read_string_attr(root, "summary", h5_path);
    info.solver_version = read_string_attr(root, "solver_version", h5_path);
    {
      Hid ds = open_dataset(root, "/mesh/nodes", h5_path);
      info.nodes = dataset_dims(ds.get(), "/mesh/nodes", h5_path)[0];
    }
    {
      Hid ds = open_dataset(root, "/mesh/triangles", h5_path);
      info.elements = dataset_dims(ds.get(), "/mesh/triangles", h5_path)[0];
    }
    // Frames are frame_00000 .. frame_{K-1}: count the links rather than trust frame_count.
    Hid fields = checked(H5Gopen2(root, "fields", H5P_DEFAULT), "open group /fields", h5_path);
    H5G_info_t ginfo{};
    checked(H5Gget_info(fields.get(), &ginfo), "get info of /fields", h5_path);
    for (hsize_t k = 0; k < ginfo.nlinks; ++k) {
      const std::string name = frame_group_name(static_cast<std::size_t>(k));
      Hid g =
          checked(H5Gopen2(fields.get(), name.c_str(), H5P_DEFAULT), "open group " + name, h5_path);
      info.frame_times.push_back(read_double_attr(g.get(), "time", h5_path));
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
  if (known == kFields.end()) {
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
  if (!known->nodal) return v;
  // Callers get (x, y) pairs from either version: N x 2 (version 1) or N x 3 (z dropped).
  const std::size_t cols = dims.size() == 2 ? static_cast<std::size_t>(dims[1]) : 0;
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
