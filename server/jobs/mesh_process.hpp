// Gmsh meshing in a child process (softshock-mesh), so that a job's cancel and wall-time limit
// reach it: Gmsh cannot be interrupted inside the daemon, but a child can be killed. The child
// meshes through the daemon's mesh cache (DATA/cache/meshes) and hands the mesh back in a file
// of the cache's format; its exit status and last stderr line become the failure's reason.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>

#include "server/store/mesh_store.hpp"
#include "softshock/v1/spec.pb.h"
#include "solver/mesh.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {

struct MesherCommand {
  std::string executable;  // softshock-mesh
  std::string cache_dir;   // empty = no cache
  std::uint64_t cache_bytes = 0;
  SpecLimits limits;  // max_elements, max_end_time_s and mesh_root are passed on
};

// The child failed: `invalid_spec` when it judged the spec (exit 2: an unreadable mesh file, too
// many elements), else a crash, a signal or an error of its own. what() is the reason, with
// the child's own words where it had any.
class MeshingFailed : public std::runtime_error {
 public:
  MeshingFailed(const std::string& what, bool invalid_spec)
      : std::runtime_error(what), invalid_spec_(invalid_spec) {}
  bool invalid_spec() const { return invalid_spec_; }

 private:
  bool invalid_spec_;
};

// Meshes the normalized spec's geometry in a child; `work_dir` (existing) holds the files
// handed over, removed before returning. should_stop() is asked every ~20 ms: once it answers
// true the child is killed and the result is nullopt. Throws MeshingFailed.
std::optional<Mesh> mesh_in_child(const MesherCommand& command, const v1::RunSpec& spec,
                                  const std::string& work_dir,
                                  const std::function<bool()>& should_stop,
                                  MeshingReport* report = nullptr);

// An uploaded mesh file checked by `softshock-mesh --check` (solver/app/softshock_mesh.cpp): the
// counts its headers declare and Gmsh's reading, in a child confined to these limits,
// so that a file that crashes Gmsh or makes it allocate without bound costs that child, never
// the daemon (a 9.7 KB file with one node tag changed to 2^63 - 1 made Gmsh segfault; a 161-byte
// header declaring 1.5e8 nodes made it take 3.2 GB).
struct MeshCheckLimits {
  std::uint64_t max_memory_bytes = std::uint64_t{2} << 30;  // the child's address space
  int max_cpu_seconds = 60;
  double max_wall_seconds = 120;  // then the child is killed
};
struct MeshFileCheck {
  std::int64_t nodes = 0, elements = 0;
  int dimension = 0;
};
// Checks `path`; the child's temporary files go into `tmp_dir` (created and removed here).
// Messages name the file as `display_name`, never by a server path. Throws
// MeshingFailed(reason, true) for a file that is not a usable mesh -- the checker refused it,
// crashed on it, ran out of memory or time on it -- and MeshingFailed(reason, false) when the
// checker could not run.
MeshFileCheck check_mesh_file_in_child(const std::string& executable, const std::string& path,
                                       const std::string& display_name, const std::string& tmp_dir,
                                       const MeshCheckLimits& limits);

// The daemon's MeshStore validator: check_mesh_file_in_child with `executable` (softshock-mesh;
// empty = none installed, every upload refused), a file it refuses as SpecError("data", ...).
MeshValidator mesh_validator_in_child(std::string executable, MeshCheckLimits limits);

// softshock-mesh beside the running executable (installed layout), else the one this build
// tree made; empty when neither exists.
std::string find_mesher();

}  // namespace softshock::server
