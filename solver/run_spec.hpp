// The run spec (proto softshock.v1.RunSpec): JSON parsing, defaults, validation, and the
// translation into a Problem + SolverOptions.
#pragma once

#include <stdexcept>
#include <string>

#include "mesh_cache.hpp"
#include "model.hpp"
#include "run_summary.hpp"
#include "softshock/v1/spec.pb.h"

namespace softshock {

// A spec that breaks a rule. field() is the JSON path (e.g. "geometry.disk.radius").
class SpecError : public std::invalid_argument {
 public:
  SpecError(std::string field, const std::string& rule)
      : std::invalid_argument(field + ": " + rule), field_(std::move(field)) {}
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

// Limits a host imposes on specs (the daemon configures them; the CLI uses the defaults).
struct SpecLimits {
  int max_elements = 2'000'000;
  double max_end_time_s = 1e-5;
  int max_modes = 1024;
  int max_threads = 256;
  int max_frames = 2000;
  int64_t max_history_samples = 1'000'000;
  // Non-empty: geometry.mesh_file is resolved inside this folder only (solver/mesh_file_path.hpp;
  // softshockd's DATA/meshes/). Empty: the path as given (softshock-solve).
  std::string mesh_root;
};

// How a spec's JSON is read: a client's (unknown fields refused, the parser naming them) or one
// stored by a daemon (unknown fields ignored: a spec written by a newer release still loads).
enum class SpecJson { kClient, kStored };
// The one JSON -> RunSpec parser (protobuf's JSON mapping). Throws SpecError("spec", parser
// message).
v1::RunSpec parse_spec_json(const std::string& json, SpecJson source = SpecJson::kClient);
// Reads and parses a spec file; throws SpecError("spec", ...) naming the path.
v1::RunSpec read_spec_file(const std::string& path);

// Copy with every absent field set to its default (the thesis baseline, docs/model.md).
v1::RunSpec with_defaults(const v1::RunSpec& spec);
// Throws SpecError for the first field breaking a rule. Expects with_defaults() applied.
void validate_spec(const v1::RunSpec& spec, const SpecLimits& limits = {});
// Defaults filled, then validated: what every entry point calls.
v1::RunSpec normalize_spec(const v1::RunSpec& spec, const SpecLimits& limits = {});

// Compact JSON with every field present (defaults filled); used in result files.
std::string spec_to_json(const v1::RunSpec& spec);

// How the mesh of make_problem came about: wall time (cache look-up included) and the cache's
// answer; `warning` says why a built mesh could not be stored (the run goes on regardless).
struct MeshingReport {
  double seconds = 0;
  MeshCacheOutcome cache = MeshCacheOutcome::kNotUsed;
  std::string warning;
};

// Meshes the geometry (Gmsh; through `cache` when given) and fills the Problem. Expects a
// normalized spec. Throws SpecError("geometry.mesh_file", ...) if a mesh file cannot be read,
// and SpecError("geometry.target_elements", ...) if the mesh exceeds limits.max_elements.
// The same as smooth_mesh() followed by make_problem_with_mesh().
Problem make_problem(const v1::RunSpec& spec, const SpecLimits& limits = {},
                     const MeshCache* cache = nullptr, MeshingReport* report = nullptr);

// Whether meshing the geometry runs Gmsh (a frontal-Delaunay disk, a rounded square, a mesh
// file): the kind that may take minutes and cannot be interrupted from inside the process.
bool meshes_with_gmsh(const v1::Geometry& geometry);
// make_problem's first half: the geometry's mesh before rim roughness (what the cache keeps),
// with the same errors. A host that meshes elsewhere (softshockd's softshock-mesh child)
// calls this there and make_problem_with_mesh() itself.
Mesh smooth_mesh(const v1::Geometry& geometry, const SpecLimits& limits = {},
                 const MeshCache* cache = nullptr, MeshingReport* report = nullptr);
// make_problem's second half: rim roughness on `mesh` (smooth_mesh's), the element limit, and
// the model parameters.
Problem make_problem_with_mesh(const v1::RunSpec& spec, Mesh mesh, const SpecLimits& limits = {});
// The nondimensional groups of a normalized spec without meshing: R0 is the disk's radius or
// half the rounded square's side. A mesh_file's R0 is known only once meshed: its tbar_pulse
// and time_scale_s are NaN.
NondimensionalGroups spec_groups(const v1::RunSpec& spec);
SolverOptions make_options(const v1::RunSpec& spec);

}  // namespace softshock
