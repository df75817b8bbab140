// What a run will cost, from its spec alone (before meshing) or from its mesh: time steps,
// peak memory and result-file size. Hosts compare these with their limits before a run starts
// (softshockd: --max-steps, --max-job-memory, --max-job-disk). Estimates, not bounds: each
// formula is meant to err on the high side by a small factor (docs/reliability.md).
//
// One function holds the stable-step estimate (stable_dt in the .cpp): when the model's time step
// changes (a physical viscosity term, say), update it and its test, nothing else.
#pragma once

#include <cmath>

#include "softshock/v1/spec.pb.h"
#include "solver/mesh.hpp"

namespace softshock {

struct ResourceEstimate {
  double dt_s = 0;   // the step while the load's shock crosses the body (dt_load)
  double steps = 0;  // time steps to run.end_time (estimate_steps)
  // mesh + the step's arrays + history (kept and copied once) + one frame + the state captured
  // where the run stops
  double memory_bytes = 0;
  // The result file (frames x fields + history + mesh) and the step's state that a SUCCEEDED job
  // keeps for ExtendJob (a running job's checkpoint holds the same).
  double disk_bytes = 0;
  double state_bytes = 0;  // that state, part of disk_bytes
};

// A mesh's smallest element altitude and the 1st percentile of its elements' altitudes
// (reference configuration), m; NaN: not known (a mesh still to be generated).
struct MeshAltitudes {
  double smallest_m = std::nan(""), percentile1_m = std::nan("");
};
MeshAltitudes mesh_altitudes(const Mesh& mesh);

// The time steps of a run. The solver's step is the smallest over the elements and follows the
// compressed ones: while the load's shock goes in (the pulse + L / U, L the crossing length, U the
// shock speed at the load, U^2 = p / (rho0 (1 - J))) and comes back to the loaded surface
// (another L / U: the passage) it is near dt_load, the stable step of the 1st-percentile element
// in the Tait state at the load's pressure (altitude shortened by J, the front's artificial
// viscosity); after it the body rings with weaker waves and the step stays below the smallest
// element's at rest, dt_rest, falling for a while as the rim's undulations grow. Each stretch's
// mean step is a factor times dt_load or dt_rest, fitted per dimension (bonded cylinder faces:
// their own), and the solver lands on every history sample, half a step more per sample
// (docs/reliability.md, "Time steps": from the mesh 1.01-1.50x the steps taken on 22 runs of
// triangles, 1.00-1.30x on 15 of tetrahedra with sliding faces, 1.00-1.37x on 42 with bonded
// faces, whose step after the passage follows the corner held by the glass; a mesh that
// collapses, as the Richtmyer-Meshkov box's jets, is not foreseen).
struct StepEstimate {
  double dt_load_s = 0, dt_rest_s = 0, passage_s = 0, steps = 0;
};
StepEstimate estimate_steps(const v1::RunSpec& spec, const MeshAltitudes& altitudes, int dim,
                            double crossing_length_m);
// The same for a given mesh: its altitudes, and its crossing length where the spec has none.
StepEstimate estimate_mesh_steps(const v1::RunSpec& spec, const Mesh& mesh);

// The whole estimate for `elements` triangles covering `area_m2` (tetrahedra filling `volume_m3`);
// altitudes: the mesh's, or NaN for a mesh still to be generated (the mesher's measured ratios to
// the mean element's altitude); crossing_length: NaN for the spec geometry's.
ResourceEstimate estimate_resources(const v1::RunSpec& spec, double elements, double area_m2,
                                    const MeshAltitudes& altitudes = {},
                                    double crossing_length = std::nan(""));
ResourceEstimate estimate_resources_3d(const v1::RunSpec& spec, double elements, double volume_m3,
                                       const MeshAltitudes& altitudes = {},
                                       double crossing_length = std::nan(""));

// The distance the load's shock crosses before it turns back: a disk's or cylinder's radius, half a
// rounded square's side, a corrugated strip's height or box's lz; NaN for a mesh file, whose
// mesh gives half its largest in-plane extent (mesh_crossing_length_m).
double crossing_length_m(const v1::RunSpec& spec);
double mesh_crossing_length_m(const Mesh& mesh);

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
