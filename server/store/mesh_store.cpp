#include "server/store/mesh_store.hpp"

#include <fcntl.h>
#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/time_util.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "server/byte_size.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/store/catalogue.hpp"
#include "server/store/resource_exhausted.hpp"
#include "solver/io/durable_file.hpp"
#include "solver/mesh_file_path.hpp"

namespace softshock::server {

namespace fs = std::filesystem;

namespace {

constexpr const char* kUploads = "uploads";
// Names of what an upload leaves while it is in progress (swept at start-up).
constexpr std::string_view kStagedPrefix = ".staged-", kCheckPrefix = ".check-";

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
  if (mesh.owner().empty()) mesh.set_owner(kDefaultUser);  // stored before owners existed
  return mesh;
}

std::string random_suffix() {
  static std::mutex mutex;
  static std::mt19937_64 rng{std::random_device{}()};
  std::lock_guard<std::mutex> lock(mutex);
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}

}  // namespace

std::string uploaded_mesh_file(const std::string& id) {
  return std::string(kUploads) + "/" + id + ".msh";
}

void check_mesh_file_name(std::string_view name) {
  if (name.empty() || name.size() > kMaxMeshFileNameBytes) {
    throw SpecError("file_name", "must be 1 to " + std::to_string(kMaxMeshFileNameBytes) +
                                     " bytes, got " + std::to_string(name.size()));
  }
  if (name == "." || name == "..") throw SpecError("file_name", "must not be '.' or '..'");
  for (unsigned char c : name) {
    if (c == '/' || c == '\\') {
      throw SpecError("file_name", "must be a file name without a folder (no '/' or '\\')");
    }
    if (c < 0x20 || c == 0x7f) {
      throw SpecError("file_name", "must not contain control characters (byte " +
                                       std::to_string(static_cast<int>(c)) + ")");
    }
  }
}

MeshStore::MeshStore(std::string meshes_dir, MeshStoreLimits limits, MeshValidator validate)
    : meshes_dir_(std::move(meshes_dir)),
      uploads_dir_((fs::path(meshes_dir_) / kUploads).string()),
      limits_(std::move(limits)),
      validate_(std::move(validate)) {
  fs::create_directories(uploads_dir_);
  sweep();
  load_index();
}

void MeshStore::load_index() {
  std::lock_guard<std::mutex> lock(write_mutex_);
  index_.clear();
  for (const auto& entry : fs::directory_iterator(uploads_dir_)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() != ".json") continue;
    const std::string id = name.substr(0, name.size() - 5);
    if (!is_mesh_id(id)) continue;
    if (auto m = get(id)) index_[id] = {m->owner(), m->size_bytes()};
  }
}

MeshUsage MeshStore::usage_locked(const std::string& owner) const {
  MeshUsage u;
  for (const auto& [id, m] : index_) {
    if (owner.empty() || m.owner == owner) {
      ++u.count;
      u.bytes += m.bytes;
    }
  }
  return u;
}

MeshUsage MeshStore::usage(const std::string& owner) const {
  std::lock_guard<std::mutex> lock(write_mutex_);
  return usage_locked(owner);
}

MeshUsage MeshStore::total_usage() const {
  return usage("");
}

void MeshStore::sweep() {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(uploads_dir_, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.starts_with(kStagedPrefix) || name.starts_with(kCheckPrefix) ||
        name.ends_with(".tmp")) {
      std::error_code ignored;
      fs::remove_all(entry.path(), ignored);
    }
  }
}

double MeshStore::free_bytes() const {
  if (limits_.free_bytes) return limits_.free_bytes(uploads_dir_);
  struct statvfs st {};
  if (::statvfs(uploads_dir_.c_str(), &st) != 0) return INFINITY;  // unknown: do not block
  return static_cast<double>(st.f_bavail) * static_cast<double>(st.f_frsize);
}

MeshStore::Upload::Upload(MeshStore& store, std::string path, int fd)
    : store_(store), path_(std::move(path)), fd_(fd) {}

MeshStore::Upload::~Upload() {
  ::close(fd_);
  if (!committed_) ::unlink(path_.c_str());
  --store_.uploads_in_progress_;
}

void MeshStore::Upload::append(std::string_view bytes) {
  if (size_ + static_cast<std::int64_t>(bytes.size()) > store_.limits_.max_bytes) {
    throw SpecError("data", "the mesh file has more than " +
                                std::to_string(store_.limits_.max_bytes) +
                                " bytes (the daemon's upload limit)");
  }
  // The reserve is looked at every 4 MiB: a disk that fills meanwhile still ends in ENOSPC below.
  const std::int64_t kCheckEvery = 4 << 20;
  if (size_ / kCheckEvery != (size_ + static_cast<std::int64_t>(bytes.size())) / kCheckEvery) {
    const double free = store_.free_bytes();
    if (free - static_cast<double>(bytes.size()) < store_.limits_.min_free_bytes) {
      throw ResourceExhausted(
          "the daemon's disk has " + byte_size(free) + " free, at its reserve of " +
          byte_size(store_.limits_.min_free_bytes) + " (delete results or meshes to make room)");
    }
  }
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == ENOSPC || errno == EDQUOT)) {
      throw ResourceExhausted("the daemon's disk is full (delete results or meshes to make room)");
    }
    if (n <= 0)
      throw std::runtime_error(std::string("cannot stage the upload: ") + std::strerror(errno));
    done += static_cast<std::size_t>(n);
  }
  hash_.update(bytes);
  size_ += static_cast<std::int64_t>(bytes.size());
}

std::unique_ptr<MeshStore::Upload> MeshStore::begin_upload() {
  if (++uploads_in_progress_ > limits_.max_concurrent_uploads) {
    --uploads_in_progress_;
    throw ResourceExhausted("the daemon is receiving " +
                            std::to_string(limits_.max_concurrent_uploads) +
                            " uploads already; retry in a moment");
  }
  int fd = -1;
  std::string path;
  try {
    if (const double free = free_bytes(); free < limits_.min_free_bytes) {
      throw ResourceExhausted("the daemon's disk has " + byte_size(free) +
                              " free, below its reserve of " + byte_size(limits_.min_free_bytes) +
                              " (delete results or meshes to make room)");
    }
    path =
        (fs::path(uploads_dir_) / (std::string(kStagedPrefix) + random_suffix() + ".msh")).string();
    fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0) {
      throw std::runtime_error(std::string("cannot stage an upload: ") + std::strerror(errno));
    }
  } catch (...) {
    --uploads_in_progress_;
    throw;
  }
  return std::unique_ptr<Upload>(new Upload(*this, path, fd));
}

v1::Mesh MeshStore::commit(Upload& upload, const std::string& file_name, const std::string& owner,
                           std::int64_t now_us) {
  check_mesh_file_name(file_name);
  if (upload.size_ == 0) throw SpecError("data", "the mesh file is empty");
  const std::string id = upload.hash_.hex_digest();
  if (auto existing = get(id)) return *existing;  // idempotent: same bytes, same mesh
  // The data on the disk before it is checked and renamed into place.
  if (::fsync(upload.fd_) != 0) {
    if (errno == ENOSPC || errno == EDQUOT) {
      throw ResourceExhausted("the daemon's disk is full (delete results or meshes to make room)");
    }
    throw std::runtime_error(std::string("cannot stage the upload: ") + std::strerror(errno));
  }
  // Checked exactly as a mesh file named by a spec is read, before anything is visible under
  // its final name; the validator names the file as the client does.
  const MeshCounts counts =
      validate_(upload.path_, file_name,
                (fs::path(uploads_dir_) / (std::string(kCheckPrefix) + random_suffix())).string());
  if (counts.elements > limits_.max_elements) {
    throw SpecError("data", "the mesh has " + std::to_string(counts.elements) +
                                " elements, more than " + std::to_string(limits_.max_elements));
  }

  v1::Mesh record;
  record.set_name("meshes/" + id);
  record.set_id(id);
  record.set_size_bytes(upload.size_);
  record.set_nodes(counts.nodes);
  record.set_elements(counts.elements);
  record.set_file_name(file_name);
  *record.mutable_create_time() = google::protobuf::util::TimeUtil::MicrosecondsToTimestamp(now_us);
  record.set_owner(owner);
  std::string json;
  (void)google::protobuf::util::MessageToJsonString(record, &json);

  std::lock_guard<std::mutex> lock(write_mutex_);
  if (auto existing = get(id)) return *existing;  // a concurrent upload of the same bytes won
  // Under the writers' lock: two uploads cannot pass a bound together.
  check_mesh_quota(limits_.quotas, owner, usage_locked(owner), usage_locked(""), upload.size_);
  // The file first, then its record: a record always has its file.
  rename_file(upload.path_, fs::path(uploads_dir_) / (id + ".msh"));
  upload.committed_ = true;
  write_durably(fs::path(uploads_dir_) / (id + ".json"), json);
  fsync_path(uploads_dir_, true);
  index_[id] = {owner, upload.size_};
  return record;
}

v1::Mesh MeshStore::add(std::string_view bytes, const std::string& file_name, std::int64_t now_us,
                        const std::string& owner) {
  auto upload = begin_upload();
  upload->append(bytes);
  return commit(*upload, file_name, owner, now_us);
}

std::optional<v1::Mesh> MeshStore::get(const std::string& id) const {
  if (!is_mesh_id(id)) return std::nullopt;
  std::error_code ec;
  if (!fs::is_regular_file(fs::path(uploads_dir_) / (id + ".msh"), ec)) return std::nullopt;
  return read_record(fs::path(uploads_dir_) / (id + ".json"));
}

std::vector<v1::Mesh> MeshStore::list(const std::string& after, int limit,
                                      const std::string& owner) const {
  std::vector<std::string> ids;
  {
    std::lock_guard<std::mutex> lock(write_mutex_);
    for (auto it = index_.upper_bound(after);
         it != index_.end() && static_cast<int>(ids.size()) < limit; ++it) {
      if (owner.empty() || it->second.owner == owner) ids.push_back(it->first);
    }
  }
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
  index_.erase(id);
  fsync_path(uploads_dir_, true);
  return had;
}

std::optional<std::string> job_using_mesh(const Catalogue& catalogue, const MeshStore& meshes,
                                          const std::string& id) {
  std::string upload;
  try {
    upload = resolve_mesh_file(meshes.meshes_dir(), uploaded_mesh_file(id));
  } catch (const SpecError&) {
    return std::nullopt;  // no such file: nothing can be using it
  }
  for (const auto& [job, mesh_file] : catalogue.unfinished_mesh_files()) {
    try {
      if (resolve_mesh_file(meshes.meshes_dir(), mesh_file) == upload) return job;
    } catch (const SpecError&) {
      // The job's mesh file is gone or never was: it is not this mesh (the job fails at start).
    }
  }
  return std::nullopt;
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
