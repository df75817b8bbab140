// HDF5 result files, writing: ResultWriter (temporary file, then flush + fsync + rename) and
// link_result_files. The layout is a contract with users: docs/results-format.md describes it,
// and a change here needs a change there (and a new format_version when it is not an addition).
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
#include "solver/io/hdf5_support.hpp"
#include "solver/io/result_file.hpp"

namespace softshock {

namespace detail {
// xdmf.cpp (private to this module, hence no header).
std::string xdmf_document(const std::string& h5_file, int dimension, std::size_t nodes,
                          std::size_t elements, const std::vector<std::string>& frame_groups,
                          const std::vector<double>& frame_times,
                          const std::vector<std::pair<std::string, bool>>& attributes,
                          const std::vector<std::string>& node_scalars);
}  // namespace detail

using namespace h5;

namespace {

namespace fs = std::filesystem;

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

// A series' `units` attribute. series_units() gives the plane-strain (2-D) units, where the
// energies are per metre of thickness; a 3-D body's energies are whole-body joules.
std::string stored_series_units(const std::string& name, int dimension) {
  std::string units = series_units(name);
  if (dimension == 3 && units == "J/m") units = "J";
  if (dimension == 3 && units == "m^2") units = "m^3";  // the damaged zone's measure
  return units;
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
  int dimension = 2;     // the mesh's: 2 (triangles) or 3 (tetrahedra)
  std::size_t nodes = 0, elements = 0;
  Hid file, fields;                       // open from construction until finish() closes them
  std::string spec_json, solver_version;  // the root attributes of every file it starts
  // Checkpoints: files sealed so far, in order (the first holds /mesh when mesh_in_file is
  // false), and the index of the first frame of the open file.
  std::vector<ResultWriter::Sealed> sealed;
  std::size_t first_frame = 0;
  bool mesh_in_file = false;
  std::vector<std::string> frame_groups;
  std::vector<double> frame_times;
  std::vector<double> xyz;  // 2-D: a node vector padded with z = 0, reused across frames
  bool damage = false;      // the frames carry the damage (kDamageField), every one of them
  bool finished = false;
  bool mesh_written = false;  // write_mesh(): finish() refuses a file without its mesh
  std::string broken;  // set when an operation failed half-way: the file is not to be trusted

  // Construction failed: nothing of this run may stay behind. Call with the HDF5 lock held.
  void discard_file() {
    fields.reset();
    file.reset();
    std::error_code ignored;
    fs::remove(tmp_h5, ignored);
  }

  // Creates the temporary file with its root attributes and /fields (HDF5 lock held).
  void create_file() {
    const std::string& path = tmp_name;
    Hid fapl = file_access_plist(path);
    // H5F_ACC_TRUNC: a .tmp left by a crashed earlier attempt is simply overwritten.
    file = checked(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()), "create file",
                   path);
    const hid_t root = file.get();
    write_string_attr(root, "spec", spec_json, path);
    write_string_attr(root, "solver_version", solver_version, path);
    write_int_attr(root, "format_version", kFormatVersion, H5T_STD_I32LE, path);
    // Readers pick the layout by it (absent in files written before 3-D: those are 2-D).
    write_int_attr(root, "dimension", dimension, H5T_STD_I32LE, path);
    write_int_attr(root, "complete", 0, H5T_STD_I32LE, path);
    write_string_attr(root, "error", "", path);
    fields = create_group(root, "fields", path, false);
  }

  // Flushes and closes the open file, reporting the final metadata writes (HDF5 lock held).
  void close_file() {
    fields.reset();
    checked(H5Fflush(file.get(), H5F_SCOPE_GLOBAL), "flush file", tmp_name);
    // H5Fclose rather than the generic close: its status reports the final metadata writes.
    // The identifier is gone whether or not it succeeded.
    if (H5Fclose(file.release()) < 0) fail("close file", tmp_name);
  }

  // finish(): the sealed files' mesh (unless the open file has it) and frames, into the open
  // file, one frame per hold of the HDF5 lock so that other runs' writers interleave.
  void copy_sealed();

  void check_usable(const char* op) const {
    if (finished) throw std::logic_error(std::string("ResultWriter::") + op + " after finish()");
    if (!broken.empty()) {
      throw std::runtime_error("result file " + tmp_name +
                               " unusable after an earlier error: " + broken);
    }
  }
};

namespace {
void check_mesh(const Mesh& mesh) {
  if (mesh.x.size() != mesh.y.size()) {
    throw std::invalid_argument("ResultWriter: mesh has " + std::to_string(mesh.x.size()) +
                                " x but " + std::to_string(mesh.y.size()) + " y coordinates");
  }
  if (mesh.dimension() == 3) {
    if (mesh.z.size() != mesh.x.size()) {
      throw std::invalid_argument("ResultWriter: 3-D mesh has " + std::to_string(mesh.x.size()) +
                                  " x but " + std::to_string(mesh.z.size()) + " z coordinates");
    }
    // A file holds one kind of element: triangles beside tetrahedra would be dropped unseen.
    if (!mesh.triangles.empty()) {
      throw std::invalid_argument("ResultWriter: mesh has both tetrahedra and triangles");
    }
  }
}
}  // namespace

ResultWriter::ResultWriter(const std::string& out_dir, const Mesh& mesh,
                           const std::string& spec_json, const std::string& solver_version,
                           MeshWrite when)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  check_mesh(mesh);
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
  m.dimension = mesh.dimension();
  m.nodes = mesh.node_count();
  m.elements = mesh.element_count();

  m.spec_json = spec_json;
  m.solver_version = solver_version;
  {
    auto lock = lock_hdf5();
    try {
      m.create_file();
    } catch (...) {
      m.discard_file();
      throw;
    }
  }
  if (when == MeshWrite::kNow) {
    try {
      write_mesh(mesh);
    } catch (...) {
      auto lock = lock_hdf5();
      m.discard_file();
      throw;
    }
  }
}

ResultWriter::ResultWriter(const std::string& out_dir, const Mesh& mesh,
                           const std::string& spec_json, const std::string& solver_version,
                           const std::vector<Sealed>& sealed,
                           const std::vector<double>& frame_times)
    : ResultWriter(out_dir, mesh, spec_json, solver_version, MeshWrite::kLater) {
  Impl& m = *impl_;
  try {
    std::size_t frames = 0;
    for (const Sealed& s : sealed) frames += s.frames;
    if (frames != frame_times.size()) {
      throw std::invalid_argument("ResultWriter: " + std::to_string(frames) +
                                  " sealed frames but " + std::to_string(frame_times.size()) +
                                  " frame times");
    }
    // Every sealed frame must be there with its time, and the mesh in the first file.
    std::size_t k = 0;
    for (const Sealed& s : sealed) {
      auto lock = lock_hdf5();
      Hid fapl = file_access_plist(s.path);
      Hid f = checked(H5Fopen(s.path.c_str(), H5F_ACC_RDONLY, fapl.get()), "open sealed frames",
                      s.path);
      if (k == 0 && H5Lexists(f.get(), "mesh", H5P_DEFAULT) <= 0)
        throw std::runtime_error("sealed frames " + s.path + " have no /mesh");
      for (std::size_t end = k + s.frames; k < end; ++k) {
        const std::string name = "fields/" + frame_group_name(k);
        Hid g = checked(H5Gopen2(f.get(), name.c_str(), H5P_DEFAULT), "open " + name, s.path);
        Hid a = checked(H5Aopen(g.get(), "time", H5P_DEFAULT), "open time of " + name, s.path);
        double t = 0;
        checked(H5Aread(a.get(), H5T_NATIVE_DOUBLE, &t), "read time of " + name, s.path);
        if (std::memcmp(&t, &frame_times[k], sizeof t) != 0)
          throw std::runtime_error("sealed frames " + s.path + ": " + name + " is of another time");
        m.frame_groups.push_back("/fields/" + frame_group_name(k));
      }
    }
  } catch (...) {
    auto lock = lock_hdf5();
    m.discard_file();
    throw;
  }
  m.sealed = sealed;
  m.frame_times = frame_times;
  m.first_frame = m.frame_groups.size();
  if (sealed.empty()) {
    write_mesh(mesh);
  } else {
    m.mesh_written = true;  // in the first sealed file, copied in by finish()
  }
}

void ResultWriter::write_mesh(const Mesh& mesh) {
  Impl& m = *impl_;
  m.check_usable("write_mesh");
  check_mesh(mesh);
  if (m.mesh_written) throw std::logic_error("ResultWriter::write_mesh: the mesh is written");
  if (mesh.dimension() != m.dimension || mesh.node_count() != m.nodes ||
      mesh.element_count() != m.elements)
    throw std::invalid_argument("ResultWriter::write_mesh: not the mesh the writer was made for");
  const std::string& path = m.tmp_name;
  // Interleaved coordinates, built before taking the lock (other runs' files wait on it).
  const std::size_t d = static_cast<std::size_t>(m.dimension);
  std::vector<double> coordinates(d * m.nodes);
  for (std::size_t i = 0; i < m.nodes; ++i) {
    coordinates[d * i] = mesh.x[i];
    coordinates[d * i + 1] = mesh.y[i];
    if (d == 3) coordinates[d * i + 2] = mesh.z[i];
  }
  static_assert(sizeof(std::array<int32_t, 3>) == 3 * sizeof(int32_t));
  static_assert(sizeof(std::array<int32_t, 4>) == 4 * sizeof(int32_t));
  auto lock = lock_hdf5();
  try {
    Hid g = create_group(m.file.get(), "mesh", path, false);
    write_doubles(g.get(), "nodes", coordinates.data(), matrix_shape(m.nodes, d), "m", path);
    if (d == 3) {
      // No outer loop in 3-D: the boundary is the outward faces (docs/results-format.md).
      write_int32s(g.get(), "tetrahedra", reinterpret_cast<const int32_t*>(mesh.tetrahedra.data()),
                   matrix_shape(m.elements, 4), path);
      write_int32s(g.get(), "boundary_faces",
                   reinterpret_cast<const int32_t*>(mesh.boundary_faces.data()),
                   matrix_shape(mesh.boundary_faces.size(), 3), path);
    } else {
      write_int32s(g.get(), "triangles", reinterpret_cast<const int32_t*>(mesh.triangles.data()),
                   matrix_shape(m.elements, 3), path);
      write_int32s(g.get(), "boundary_nodes", mesh.boundary_nodes.data(),
                   vector_shape(mesh.boundary_nodes.size()), path);
    }
  } catch (const std::exception& e) {
    m.broken = std::string("writing the mesh: ") + e.what();
    throw;
  }
  m.mesh_written = true;
  m.mesh_in_file = true;
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
  if (frame.dimension != m.dimension) {
    throw std::invalid_argument("ResultWriter::write_frame: frame of dimension " +
                                std::to_string(frame.dimension) + " for a mesh of dimension " +
                                std::to_string(m.dimension));
  }
  const std::size_t d = static_cast<std::size_t>(m.dimension);
  for (const FieldSpec& f : kFields) {
    const std::size_t expected = f.nodal ? d * m.nodes : m.elements;
    const std::size_t got = (frame.*f.member).size();
    if (got != expected) {
      throw std::invalid_argument("ResultWriter::write_frame: field " + std::string(f.name) +
                                  " has " + std::to_string(got) + " values, expected " +
                                  std::to_string(expected));
    }
  }
  // The damage: in every frame of a run with damage, in none of one without.
  const bool damage = !(frame.*kDamageField.member).empty();
  if (damage && (frame.*kDamageField.member).size() != m.nodes)
    throw std::invalid_argument("ResultWriter::write_frame: field damage has " +
                                std::to_string((frame.*kDamageField.member).size()) +
                                " values, expected " + std::to_string(m.nodes));
  if (!m.frame_groups.empty() && damage != m.damage)
    throw std::invalid_argument("ResultWriter::write_frame: the damage field in some frames only");
  const std::string name = frame_group_name(m.frame_groups.size());
  const std::string& path = m.tmp_name;
  {
    auto lock = lock_hdf5();
    try {
      Hid g = create_group(m.fields.get(), name.c_str(), path, false);
      write_double_attr(g.get(), "time", frame.time_s, path);
      if (damage)
        write_doubles(g.get(), kDamageField.name, (frame.*kDamageField.member).data(),
                      vector_shape(m.nodes), kDamageField.units, path);
      for (const FieldSpec& f : kFields) {
        const std::vector<double>& v = frame.*f.member;
        if (!f.nodal) {
          write_doubles(g.get(), f.name, v.data(), vector_shape(m.elements), f.units, path);
          continue;
        }
        if (d == kVectorColumns) {  // 3-D: already N x 3
          write_doubles(g.get(), f.name, v.data(), matrix_shape(m.nodes, kVectorColumns), f.units,
                        path);
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
  }  // the HDF5 lock: other runs' files need it, the sync below does not
  m.frame_groups.push_back("/fields/" + name);
  m.frame_times.push_back(frame.time_s);
  m.damage = damage;
  // The frame's data is with the OS: written to the disk here, on the writer thread beside the
  // run, rather than all in finish()'s fsync, which the run waits for (t-bar = 4 point, 17 MB:
  // 15 ms, and 1.7 ms with ~2 ms per frame here, measured; sync_file_range's writeback alone left
  // 10 ms of it, the journal's).
  write_back(m.tmp_h5);
}

void ResultWriter::seal_segment(const std::string& path) {
  Impl& m = *impl_;
  m.check_usable("seal_segment");
  if (!m.mesh_written) throw std::logic_error("ResultWriter::seal_segment before write_mesh()");
  const fs::path target(path);
  if (target == m.final_h5 || target == m.tmp_h5)
    throw std::invalid_argument("ResultWriter::seal_segment: not a name of its own");
  // Nothing new since the last seal: the sealed files already hold every frame.
  if (!m.sealed.empty() && m.frame_groups.size() == m.first_frame) return;
  try {
    {
      auto lock = lock_hdf5();
      m.close_file();
    }
    fsync_path(m.tmp_h5, false);
    rename_file(m.tmp_h5, target);
    const fs::path folder = target.has_parent_path() ? target.parent_path() : fs::path(".");
    fsync_path(folder, true);
    if (fs::absolute(folder) != fs::absolute(m.dir)) fsync_path(m.dir, true);
    m.sealed.push_back({target.string(), m.frame_groups.size() - m.first_frame});
    m.first_frame = m.frame_groups.size();
    m.mesh_in_file = false;
    auto lock = lock_hdf5();
    m.create_file();
  } catch (const std::exception& e) {
    m.broken = std::string("sealing frames: ") + e.what();
    throw;
  }
}

const std::vector<ResultWriter::Sealed>& ResultWriter::sealed() const {
  return impl_->sealed;
}

const std::vector<double>& ResultWriter::frame_times() const {
  return impl_->frame_times;
}

void ResultWriter::Impl::copy_sealed() {
  std::size_t k = 0;
  for (std::size_t i = 0; i < sealed.size(); ++i) {
    const std::string& from = sealed[i].path;
    auto lock = lock_hdf5();
    Hid fapl = file_access_plist(from);
    Hid src =
        checked(H5Fopen(from.c_str(), H5F_ACC_RDONLY, fapl.get()), "open sealed frames", from);
    if (i == 0 && !mesh_in_file) {
      checked(H5Ocopy(src.get(), "mesh", file.get(), "mesh", H5P_DEFAULT, H5P_DEFAULT),
              "copy /mesh from " + from + " into", tmp_name);
      mesh_in_file = true;
    }
    for (std::size_t end = k + sealed[i].frames; k < end; ++k) {
      lock.unlock();  // between frames: other runs' files take their turn
      lock.lock();
      const std::string name = frame_group_name(k);
      checked(H5Ocopy(src.get(), ("fields/" + name).c_str(), fields.get(), name.c_str(),
                      H5P_DEFAULT, H5P_DEFAULT),
              "copy frame " + name + " from " + from + " into", tmp_name);
    }
  }
}

void ResultWriter::finish(const History& history, const RunSummary& summary, bool complete,
                          const std::string& error) {
  Impl& m = *impl_;
  m.check_usable("finish");
  if (!m.mesh_written) throw std::logic_error("ResultWriter::finish before write_mesh()");
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
  // Rows of mode amplitudes as one row-major matrix (all rows the same length).
  auto matrix = [](const std::vector<std::vector<double>>& rows, std::size_t& cols) {
    cols = rows.empty() ? 0 : rows.front().size();
    std::vector<double> out;
    out.reserve(rows.size() * cols);
    for (const auto& row : rows) {
      if (row.size() != cols) {
        throw std::invalid_argument("ResultWriter::finish: mode samples differ in length");
      }
      out.insert(out.end(), row.begin(), row.end());
    }
    return out;
  };
  std::size_t mode_cols = 0, z_mean_cols = 0;
  const std::vector<double> amplitudes = matrix(history.modes, mode_cols);
  // 3-D: the modes averaged over the thickness too (History::modes_z_mean).
  if (!history.modes_z_mean.empty() && history.modes_z_mean.size() != samples) {
    throw std::invalid_argument(
        "ResultWriter::finish: " + std::to_string(history.modes_z_mean.size()) +
        " z-mean mode samples for " + std::to_string(samples));
  }
  const std::vector<double> z_mean = matrix(history.modes_z_mean, z_mean_cols);
  const std::string summary_json = summary_to_json(summary);

  const std::string& path = m.tmp_name;
  try {
    m.copy_sealed();
    {
      auto lock = lock_hdf5();
      const hid_t root = m.file.get();
      Hid ts = create_group(root, "timeseries", path, true);
      for (const auto& [name, column] : columns) {
        const std::string units = stored_series_units(name, m.dimension);
        write_doubles(ts.get(), name.c_str(), column->data(), vector_shape(column->size()),
                      units.c_str(), path);
      }
      Hid modes = create_group(root, "modes", path, false);
      const std::size_t mode_rows = history.modes.size();
      write_doubles(modes.get(), "time", history.time.data(), vector_shape(mode_rows), "s", path);
      write_doubles(modes.get(), "amplitude", amplitudes.data(), matrix_shape(mode_rows, mode_cols),
                    "1", path);
      if (!history.modes_z_mean.empty()) {
        write_doubles(modes.get(), "amplitude_z_mean", z_mean.data(),
                      matrix_shape(history.modes_z_mean.size(), z_mean_cols), "1", path);
      }

      write_string_attr(root, "summary", summary_json, path);
      write_int_attr(root, "steps", summary.steps, H5T_STD_I64LE, path);
      write_double_attr(root, "wall_time_s", summary.wall_time_s, path);
      write_int_attr(root, "frame_count", static_cast<int64_t>(m.frame_groups.size()),
                     H5T_STD_I64LE, path);
      write_string_attr(root, "error", error, path);
      write_int_attr(root, "complete", complete ? 1 : 0, H5T_STD_I32LE, path);

      ts.reset();
      modes.reset();
      m.close_file();
    }
    // Data on disk before the name: after a crash result.h5 is either absent or whole.
    fsync_path(m.tmp_h5, false);
    std::vector<std::pair<std::string, bool>> attributes;
    for (const FieldSpec& f : kFields) attributes.emplace_back(f.name, f.nodal);
    std::vector<std::string> node_scalars;
    if (m.damage) node_scalars.emplace_back(kDamageField.name);
    write_file_synced(
        m.tmp_xdmf, detail::xdmf_document(kH5Name, m.dimension, m.nodes, m.elements, m.frame_groups,
                                          m.frame_times, attributes, node_scalars));
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

}  // namespace softshock
