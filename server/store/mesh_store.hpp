// Meshes uploaded by clients: DATA/meshes/uploads/{id}.msh, id = SHA-256 of the bytes, with a
// {id}.json record (the Mesh message) beside it; and the daemon's rules for the mesh a spec names
// (geometry.mesh_id and geometry.mesh_file, both resolved under DATA/meshes/).
//
// An upload streams to a staged file (uploads/.staged-*) as it arrives -- never whole in memory --
// and is hashed on the way; the bytes are checked by a validator the daemon gives (a confined
// child process, server/jobs/mesh_process.hpp: Gmsh never reads an uploaded file inside the
// daemon), then renamed into place. Every failure removes its staged file; what a crash leaves
// (staged files, the checker's folders) is swept when the store opens.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <string_view>
#include <vector>

#include "server/jobs/grid.hpp"
#include "server/policy/quotas.hpp"
#include "server/policy/users.hpp"
#include "server/store/spec_hash.hpp"
#include "softshock/v1/service.pb.h"
#include "solver/run_spec.hpp"

namespace softshock::server {

// The one place that maps an uploaded mesh to its file: "uploads/{id}.msh", relative to
// DATA/meshes/ (geometry.mesh_file's root).
std::string uploaded_mesh_file(const std::string& id);

// What a validator found in a usable mesh file.
struct MeshCounts {
  std::int64_t nodes = 0, elements = 0;
};
// Checks the staged file at `path` (the client knows it as `display_name`), with `scratch_dir`
// (not yet existing; swept at start-up) for any files of its own; throws SpecError("data", rule)
// for bytes that are not a usable mesh, anything else when it could not check.
using MeshValidator = std::function<MeshCounts(
    const std::string& path, const std::string& display_name, const std::string& scratch_dir)>;

// Longest file_name an upload may carry (bytes; a file name on Linux).
inline constexpr std::size_t kMaxMeshFileNameBytes = 255;
// Throws SpecError("file_name", rule) unless `name` is a plain file name: 1 to 255 bytes, no
// '/' or '\\', no control characters, not "." or "..".
void check_mesh_file_name(std::string_view name);

struct MeshStoreLimits {
  std::int64_t max_bytes = 64ll << 20;  // largest upload
  std::int64_t max_elements = 2'000'000;
  int max_concurrent_uploads = 4;
  // Uploads leave at least this much free on the data folder's file system (the jobs' reserve).
  double min_free_bytes = 256.0 * (1 << 20);
  // Free bytes of the folder; unset = statvfs.
  std::function<double(const std::string& dir)> free_bytes;
  // Stored meshes by count and bytes, per user and in all (the max_meshes* fields).
  QuotaLimits quotas;
};

class Catalogue;

class MeshStore {
 public:
  // meshes_dir: DATA/meshes (uploads/ is created inside, and swept of what a crash left).
  MeshStore(std::string meshes_dir, MeshStoreLimits limits, MeshValidator validate);

  const std::string& meshes_dir() const { return meshes_dir_; }
  std::int64_t max_bytes() const { return limits_.max_bytes; }

  // One upload in progress: a staged file that grows as parts arrive. Removed unless committed.
  class Upload {
   public:
    ~Upload();
    Upload(const Upload&) = delete;
    Upload& operator=(const Upload&) = delete;
    // Throws SpecError("data", ...) past the size limit, ResourceExhausted when the disk (or its
    // reserve) is full.
    void append(std::string_view bytes);
    std::int64_t size() const { return size_; }

   private:
    friend class MeshStore;
    Upload(MeshStore& store, std::string path, int fd);
    MeshStore& store_;
    std::string path_;
    int fd_;
    std::int64_t size_ = 0;
    Sha256 hash_;
    bool committed_ = false;
  };
  // Throws ResourceExhausted when max_concurrent_uploads are in progress or the disk is within
  // its reserve.
  std::unique_ptr<Upload> begin_upload();
  // Validates the staged bytes and stores them, owned by `owner`, unless a mesh with the same id
  // exists (then returns that one, whoever owns it: the same bytes are one mesh, counted against
  // its first uploader). `file_name` must pass check_mesh_file_name. Throws SpecError("data",
  // rule) for bytes that are not a usable mesh, ResourceExhausted when a new mesh would pass a
  // quota (limits.quotas; checked with the id known, so re-sending a stored mesh always works).
  v1::Mesh commit(Upload& upload, const std::string& file_name, const std::string& owner,
                  std::int64_t now_us);
  // begin_upload + append + commit, for bytes already at hand.
  v1::Mesh add(std::string_view bytes, const std::string& file_name, std::int64_t now_us,
               const std::string& owner = kDefaultUser);

  // A record without an owner (stored before owners existed) reads as the default user's.
  std::optional<v1::Mesh> get(const std::string& id) const;
  // Ids in increasing order after `after` (exclusive), at most `limit`; owner empty = any.
  std::vector<v1::Mesh> list(const std::string& after, int limit,
                             const std::string& owner = "") const;
  // Removes the mesh; false when there was none.
  bool remove(const std::string& id);
  // What `owner` stores (count, bytes), and what everyone does.
  MeshUsage usage(const std::string& owner) const;
  MeshUsage total_usage() const;

  // Submissions hold this shared while they resolve and insert a job; DeleteMesh holds it
  // exclusively while it checks for users and removes, so no job can start using a mesh that is
  // being deleted.
  std::shared_lock<std::shared_mutex> hold_for_submit() const {
    return std::shared_lock<std::shared_mutex>(use_mutex_);
  }
  std::unique_lock<std::shared_mutex> hold_for_delete() const {
    return std::unique_lock<std::shared_mutex>(use_mutex_);
  }

 private:
  double free_bytes() const;
  void sweep();  // staged files, temporary records and checker folders a crash left
  void load_index();
  MeshUsage usage_locked(const std::string& owner) const;

  struct Indexed {
    std::string owner;
    std::int64_t bytes = 0;
  };
  std::string meshes_dir_, uploads_dir_;
  MeshStoreLimits limits_;
  MeshValidator validate_;
  std::atomic<int> uploads_in_progress_{0};
  mutable std::shared_mutex use_mutex_;
  mutable std::mutex write_mutex_;        // one writer of uploads/ at a time; guards index_
  std::map<std::string, Indexed> index_;  // every stored mesh by id: owner and size
};

// The first QUEUED or RUNNING job whose spec names the uploaded mesh `id`, if any. Specs are
// compared by what their geometry.mesh_file resolves to under DATA/meshes/ (the path rules of
// solver/mesh_file_path.hpp: every symlink followed), not by their text, so "uploads/./ID.msh" or
// a symlink to the upload is found as well as "uploads/ID.msh".
std::optional<std::string> job_using_mesh(const Catalogue& catalogue, const MeshStore& meshes,
                                          const std::string& id);

// canonical_spec() as the daemon applies it to a submitted spec: geometry.mesh_id becomes
// mesh_file "uploads/{id}.msh" (the mesh must exist); limits.mesh_root (DATA/meshes/) makes
// mesh_file a relative path resolved there only, and the stored spec keeps that relative path.
// Throws SpecError.
CanonicalSpec daemon_canonical_spec(const v1::RunSpec& spec, const SpecLimits& limits,
                                    const MeshStore& meshes);

}  // namespace softshock::server
