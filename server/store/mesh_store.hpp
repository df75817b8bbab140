// Meshes uploaded by clients: DATA/meshes/uploads/{id}.msh, id = SHA-256 of the bytes, with a
// {id}.json record (the Mesh message) beside it; and the daemon's rules for the mesh a spec names
// (geometry.mesh_id and geometry.mesh_file, both resolved under DATA/meshes/).
#pragma once

#include <cstdint>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <vector>

#include "server/jobs/grid.hpp"
#include "softshock/v1/service.pb.h"
#include "solver/run_spec.hpp"

namespace softshock::server {

// The one place that maps an uploaded mesh to its file: "uploads/{id}.msh", relative to
// DATA/meshes/ (geometry.mesh_file's root).
std::string uploaded_mesh_file(const std::string& id);

class MeshStore {
 public:
  // meshes_dir: DATA/meshes (uploads/ is created inside). max_bytes: largest upload.
  MeshStore(std::string meshes_dir, int64_t max_bytes, int64_t max_elements);

  const std::string& meshes_dir() const { return meshes_dir_; }
  int64_t max_bytes() const { return max_bytes_; }

  // Stores the bytes unless a mesh with the same id exists (then returns that one). Throws
  // SpecError("data", rule) for bytes that are not a usable mesh.
  v1::Mesh add(const std::string& bytes, const std::string& file_name, int64_t now_us);
  std::optional<v1::Mesh> get(const std::string& id) const;
  // Ids in increasing order after `after` (exclusive), at most `limit`.
  std::vector<v1::Mesh> list(const std::string& after, int limit) const;
  // Removes the mesh; false when there was none.
  bool remove(const std::string& id);

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
  std::string meshes_dir_, uploads_dir_;
  int64_t max_bytes_, max_elements_;
  mutable std::shared_mutex use_mutex_;
  mutable std::mutex write_mutex_;  // one writer of uploads/ at a time
};

// canonical_spec() as the daemon applies it to a submitted spec: geometry.mesh_id becomes
// mesh_file "uploads/{id}.msh" (the mesh must exist); limits.mesh_root (DATA/meshes/) makes
// mesh_file a relative path resolved there only, and the stored spec keeps that relative path.
// Throws SpecError.
CanonicalSpec daemon_canonical_spec(const v1::RunSpec& spec, const SpecLimits& limits,
                                    const MeshStore& meshes);

}  // namespace softshock::server
