// A content-addressed cache of finished meshes on disk, so a grid over loads or materials
// meshes its geometry once and a repeated run never does (and never loads Gmsh).
//
// An entry is one file DIR/<key>.mesh: the key material (what the key was hashed from), the
// mesh's arrays, and a checksum of all of it. Writers write a private temporary file and
// rename it, so a reader sees a whole entry or none, also after kill -9. A reader that finds a
// bad checksum, a foreign key or inconsistent arrays treats the entry as absent (and the
// rebuilt mesh replaces it). Builders of the same key take a lock file (flock: released by the
// kernel when a process dies), so concurrent workers mesh a geometry once. The directory is
// bounded by bytes: least recently used entries (by mtime, refreshed on every hit) go first.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "softshock/v1/spec.pb.h"
#include "solver/mesh.hpp"

namespace softshock {

enum class MeshCacheOutcome {
  kNotUsed,   // no cache, or a geometry that is not cached
  kHit,       // read from the cache
  kMiss,      // built and stored
  kReplaced,  // an unusable (corrupt, foreign) entry was found, rebuilt and replaced
};
const char* to_string(MeshCacheOutcome outcome);

class MeshCache {
 public:
  // Creates `dir` if needed; throws std::runtime_error if it cannot. max_bytes bounds the total
  // size of the entries (an entry larger than the bound is not stored).
  MeshCache(std::string dir, std::uint64_t max_bytes);

  // The mesh stored under `key`, else build() stored under it. `material` is the key's source
  // (stored and compared on read, so a hash collision is a miss, never a wrong mesh). Storage
  // errors (disk full, permissions) are not the run's problem: the built mesh is returned and
  // the problem reported in *warning. build()'s exceptions propagate.
  Mesh get_or_build(const std::string& key, const std::string& material,
                    const std::function<Mesh()>& build, MeshCacheOutcome* outcome = nullptr,
                    std::string* warning = nullptr) const;

  // Lower-level steps, public for tests. load(): nullopt when absent or unusable (*unusable
  // set for the latter). store(): temporary file + rename, then evict(); throws
  // std::runtime_error. evict(): removes the least recently used entries until the total is
  // within the bound, and temporary files left by killed writers.
  std::optional<Mesh> load(const std::string& key, const std::string& material,
                           bool* unusable = nullptr) const;
  void store(const std::string& key, const std::string& material, const Mesh& mesh) const;
  void evict() const;

  std::string entry_path(const std::string& key) const;
  const std::string& dir() const { return dir_; }
  std::uint64_t max_bytes() const { return max_bytes_; }

 private:
  std::string dir_;
  std::uint64_t max_bytes_;
};

// The key material of a normalized geometry: a format version, the mesher's revision, the
// Gmsh release and the geometry message serialized deterministically (every field, so fields
// added later are covered). nullopt for geometries that are not cached: mesh_file (read, not
// meshed; its content may change under the same name).
std::optional<std::string> mesh_key_material(const v1::Geometry& geometry);
// Key material for any geometry, mesh_file included: mesh_key_material's where there is one.
// What a mesh handed from one process to another in an entry file is checked against.
std::string mesh_entry_material(const v1::Geometry& geometry);
// 32 hex digits (128 bits) hashed from the material: the entry's file name.
std::string mesh_cache_key(const std::string& material);

// One entry as a file of its own, in the cache's format (key material, arrays, checksum):
// how softshock-mesh hands a mesh to softshockd. write_mesh_entry() writes a temporary file
// beside `path` and renames it (throws std::runtime_error); read_mesh_entry() is nullopt when
// the file is absent or unusable (*unusable set for the latter).
void write_mesh_entry(const std::string& path, const std::string& material, const Mesh& mesh);
std::optional<Mesh> read_mesh_entry(const std::string& path, const std::string& material,
                                    bool* unusable = nullptr);

// softshock-solve's cache folder: $SOFTSHOCK_MESH_CACHE, else $XDG_CACHE_HOME/softshock/meshes,
// else $HOME/.cache/softshock/meshes; empty when none applies or SOFTSHOCK_MESH_CACHE is "off".
std::string default_mesh_cache_dir();
// $SOFTSHOCK_MESH_CACHE_BYTES, else 512 MiB. Throws std::invalid_argument on a bad value.
std::uint64_t default_mesh_cache_bytes();

}  // namespace softshock
