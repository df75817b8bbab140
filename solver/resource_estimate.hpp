// What a run will cost, from its spec alone (before meshing) or from its mesh: time steps,
// peak memory and result-file size. Hosts compare these with their limits before a run starts
// (softshockd: --max-steps, --max-job-memory, --max-job-disk). Estimates, not bounds: each
// formula is meant to err on the high side by a small factor (docs/reliability.md).
//
// One function holds the stable-step estimate: when the model's time step changes (a physical
// viscosity term, say), update estimate_stable_dt() and its test, nothing else.
#pragma once

#include "softshock/v1/spec.pb.h"
#include "solver/mesh.hpp"

namespace softshock {

struct ResourceEstimate {
  double dt_s = 0;          // stable time step at the load (smallest element, compressed)
  double steps = 0;         // end_time / dt_s
  double memory_bytes = 0;  // mesh + state + history (kept and copied once) + one frame
  double disk_bytes = 0;    // frames x fields + history + mesh
};

// The stable step of a normalized spec's material at the load: the Tait law K(J) = kappa J^-n
// (n = gamma + 1) at pressure P gives J^-n = 1 + n P / kappa; c^2 = (K + 4 mu / 3) J / rho0;
// the smallest altitude h of a triangle of mean area area/elements (a fifth of an equilateral
// triangle's, for mesh grading) shrinks with J. dt = cfl h J / c.
double estimate_stable_dt(const v1::RunSpec& spec, double elements, double area_m2);

// The whole estimate for `elements` triangles covering `area_m2`.
ResourceEstimate estimate_resources(const v1::RunSpec& spec, double elements, double area_m2);

// The same for tetrahedra: the smallest altitude taken as a fifth of the regular tetrahedron's
// of the mean volume (the extruded ring meshes' worst is ~0.4 of it), shrunk by J under the load;
// memory and frames per tetrahedron measured (docs/reliability.md).
double estimate_stable_dt_3d(const v1::RunSpec& spec, double elements, double volume_m3);
ResourceEstimate estimate_resources_3d(const v1::RunSpec& spec, double elements, double volume_m3);

// The reference area of a normalized spec's 2-D geometry (disk, rounded square, strip), the volume
// of a 3-D one (cylinder, corrugated box); NaN for a mesh_file (known once meshed) and for the
// other dimension's shapes.
double spec_area_m2(const v1::RunSpec& spec);
double spec_volume_m3(const v1::RunSpec& spec);
// The estimate from the spec alone (NaN fields for a mesh_file), or from a mesh (its own area or
// volume and element count): what admission control compares with the host's limits.
ResourceEstimate estimate_spec_resources(const v1::RunSpec& spec);
ResourceEstimate estimate_mesh_resources(const v1::RunSpec& spec, const Mesh& mesh);

}  // namespace softshock
