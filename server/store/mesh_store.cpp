#include "server/store/mesh_store.hpp"

#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/time_util.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "server/jobs/job_runner.hpp"
#include "server/store/spec_hash.hpp"
#include "solver/gmsh_mesher.hpp"
#include "solver/io/durable_file.hpp"

namespace softshock::server {

namespace fs = std::filesystem;

namespace {

constexpr const char* kUploads = "uploads";

bool is_mesh_id(const std::string& id) {
  return id.size() == 64 && std::all_of(id.begin(), id.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

// Written in full under a temporary name, then renamed: a reader (or a crash) never sees half.
void write_durably(const fs::path& path, const std::string& bytes) {
  const fs::path tmp = path.string() + ".tmp";
  write_file_synced(tmp, bytes);
  rename_file(tmp, path);
}

std::optional<v1::Mesh> read_record(const fs::path& json_path) {
  std::ifstream in(json_path);
  if (!in) return std::nullopt;
  std::stringstream text;
  text << in.rdbuf();
  v1::Mesh mesh;
  if (!google::protobuf::util::JsonStringToMessage(text.str(), &mesh).ok()) return std::nullopt;
  return mesh;
}

}  // namespace

std::string uploaded_mesh_file(const std::string& id) {
  return std::string(kUploads) + "/" + id + ".msh";
}

MeshStore::MeshStore(std::string meshes_dir, int64_t max_bytes, int64_t max_elements)
    : meshes_dir_(std::move(meshes_dir)),
      uploads_dir_((fs::path(meshes_dir_) / kUploads).string()),
      max_bytes_(max_bytes),
      max_elements_(max_elements) {
  fs::create_directories(uploads_dir_);
}

v1::Mesh MeshStore::add(const std::string& bytes, const std::string& file_name, int64_t now_us) {
  if (bytes.empty()) throw SpecError("data", "the mesh file is empty");
  if (static_cast<int64_t>(bytes.size()) > max_bytes_) {
    throw SpecError("data", "the mesh file has more than " + std::to_string(max_bytes_) +
                                " bytes (the daemon's upload limit)");
  }
  const std::string id = sha256_hex(bytes);
  if (auto existing = get(id)) return *existing;  // idempotent: same bytes, same mesh

  // Validate exactly as a mesh file named by a spec is read (Gmsh picks the format by the
  // extension, hence .msh), before anything is visible under the final name.
  std::random_device rd;
  const fs::path staged = fs::path(uploads_dir_) /
                          (".staged-" + std::to_string(rd()) + "-" + id.substr(0, 12) + ".msh");
  Mesh mesh;
  try {
    write_durably(staged, bytes);
    mesh = read_gmsh_file(staged.string());
  } catch (const std::exception& e) {
    std::error_code ignored;
    fs::remove(staged, ignored);
    std::string why = e.what();
    const std::size_t at = why.find(staged.string());  // the client never saw this path
    if (at != std::string::npos) why.replace(at, staged.string().size(), file_name);
    throw SpecError("data", "not a usable Gmsh mesh: " + why);
  }
  if (static_cast<int64_t>(mesh.element_count()) > max_elements_) {
    std::error_code ignored;
    fs::remove(staged, ignored);
    throw SpecError("data", "the mesh has " + std::to_string(mesh.element_count()) +
                                " elements, more than " + std::to_string(max_elements_));
  }
  v1::Mesh record;
  record.set_name("meshes/" + id);
  record.set_id(id);
  record.set_size_bytes(static_cast<int64_t>(bytes.size()));
  record.set_nodes(static_cast<int64_t>(mesh.node_count()));
  record.set_elements(static_cast<int64_t>(mesh.element_count()));
  record.set_file_name(fs::path(file_name).filename().string());
  *record.mutable_create_time() = google::protobuf::util::TimeUtil::MicrosecondsToTimestamp(now_us);
  std::string json;
  (void)google::protobuf::util::MessageToJsonString(record, &json);

  std::lock_guard<std::mutex> lock(write_mutex_);
  if (auto existing = get(id)) {  // a concurrent upload of the same bytes won
    std::error_code ignored;
    fs::remove(staged, ignored);
    return *existing;
  }
  // The file first, then its record: a record always has its file.
  fs::rename(staged, fs::path(uploads_dir_) / (id + ".msh"));
  write_durably(fs::path(uploads_dir_) / (id + ".json"), json);
  fsync_path(uploads_dir_, true);
  return record;
}

std::optional<v1::Mesh> MeshStore::get(const std::string& id) const {
  if (!is_mesh_id(id)) return std::nullopt;
  std::error_code ec;
  if (!fs::is_regular_file(fs::path(uploads_dir_) / (id + ".msh"), ec)) return std::nullopt;
  return read_record(fs::path(uploads_dir_) / (id + ".json"));
}

std::vector<v1::Mesh> MeshStore::list(const std::string& after, int limit) const {
  std::vector<std::string> ids;
  for (const auto& entry : fs::directory_iterator(uploads_dir_)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() != ".json") continue;
    const std::string id = name.substr(0, name.size() - 5);
    if (is_mesh_id(id) && id > after) ids.push_back(id);
  }
  std::sort(ids.begin(), ids.end());
  std::vector<v1::Mesh> out;
  for (const auto& id : ids) {
    if (static_cast<int>(out.size()) >= limit) break;
    if (auto m = get(id)) out.push_back(std::move(*m));
  }
  return out;
}

bool MeshStore::remove(const std::string& id) {
  if (!is_mesh_id(id)) return false;
  std::lock_guard<std::mutex> lock(write_mutex_);
  std::error_code ec;
  // The record first: a file without a record is invisible and is replaced by a re-upload.
  const bool had = fs::remove(fs::path(uploads_dir_) / (id + ".json"), ec);
  fs::remove(fs::path(uploads_dir_) / (id + ".msh"), ec);
  fsync_path(uploads_dir_, true);
  return had;
}

// ---- specs -------------------------------------------------------------------------------------

namespace {

// geometry.mesh_id -> geometry.mesh_file "uploads/{id}.msh".
v1::RunSpec resolve_mesh_id(v1::RunSpec spec, const MeshStore& meshes) {
  v1::Geometry* g = spec.mutable_geometry();
  if (g->mesh_id().empty()) return spec;
  std::string id = g->mesh_id();
  if (id.rfind("meshes/", 0) == 0) id = id.substr(7);
  if (g->shape_case() != v1::Geometry::SHAPE_NOT_SET) {
    throw SpecError("geometry.mesh_id",
                    "cannot be combined with geometry.disk, rounded_square or mesh_file");
  }
  if (!meshes.get(id)) {
    throw SpecError("geometry.mesh_id", "no uploaded mesh '" + g->mesh_id() +
                                            "' (upload it first: softshock mesh upload FILE)");
  }
  g->clear_mesh_id();
  g->set_mesh_file(uploaded_mesh_file(id));
  return spec;
}

}  // namespace

CanonicalSpec daemon_canonical_spec(const v1::RunSpec& spec, const SpecLimits& limits,
                                    const MeshStore& meshes) {
  // limits.mesh_root (DATA/meshes/) confines mesh_file there (solver/mesh_file_path.hpp).
  return canonical_spec(resolve_mesh_id(spec, meshes), limits);
}

}  // namespace softshock::server
