#include "solver/resource_estimate.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "solver/continuum.hpp"
#include "solver/damage/damage_solver.hpp"
#include "solver/integrator.hpp"

namespace softshock {

namespace {

// Measured (docs/deploy.md): ~67 MB fixed, ~0.85 kB per element at peak.
constexpr double kFixedBytes = 67e6;
constexpr double kBytesPerElement = 850;
// History columns besides the modes (time, energies, A-bar, centre/rim figures, dt, the
// Delta-t-setting element, the interval's smallest dt: History::columns()).
constexpr double kHistoryColumns = 20;
// A frame, stored raw (docs/results-format.md): 6 element fields (J, aspect ratio, four
// stresses) and 2 node vectors of 3 columns (nodes ~ elements / 2), doubles; plus the group's
// and its 8 datasets' HDF5 object headers.
constexpr double kFrameBytesPerElement = 6 * 8 + 0.5 * 2 * 3 * 8;
constexpr double kFrameOverheadBytes = 16e3;
// Mesh in the result file: nodes (2 doubles) and triangles (3 int32) per element, roughly.
constexpr double kMeshBytesPerElement = 0.5 * 16 + 12;

// Tetrahedra: softshock-solve's peak resident size (2026-12-05, docs/deploy.md) was 22.6 / 29.6 /
// 67.6 / 189.0 MB at 5,340 / 19,332 / 104,292 / 403,218 tetrahedra of the generated cylinder
// (~20 MB fixed, 400-460 B per tetrahedron; the box alike), and 75.7 / 110.5 MB at 20,250 /
// 105,456 tetrahedra read from a .msh file, which loads Gmsh into the process (~67 MB fixed).
// Taken as 24 MB (70 MB with Gmsh) and 460 B per tetrahedron, plus a frame's fields.
constexpr double kFixedBytes3d = 24e6;
constexpr double kFixedBytes3dWithGmsh = 70e6;
constexpr double kBytesPerTetrahedron = 460;
// Phase-field damage: its matrix, the pattern's analysis and the solver's vectors took +10 / +35 /
// +206 MB at 19k tetrahedra / 66k triangles / 403k tetrahedra (520-530 B per element), taken as
// 600 B; the direct solver's LDLT factor (AUTO: up to direct_max_nodes) another +46 / +131 MB on
// 21.8k / 33.3k-node tetrahedral meshes (~ nodes^2.5; the triangles' factor is within the 600 B).
constexpr double kDamageBytesPerElement = 600;
constexpr double kDamageFactorBytes3d = 55e6;  // at kDamageFactorNodes3d nodes, ~ nodes^2.5
constexpr double kDamageFactorNodes3d = 21800;
constexpr double kNodesPerTetrahedron = 0.22;
constexpr double kFrameBytesPerTetrahedron = 6 * 8 + kNodesPerTetrahedron * 2 * 3 * 8;
// Nodes (3 doubles), tetrahedra (4 int32), boundary faces (3 int32, ~0.1 per tetrahedron).
constexpr double kMeshBytesPerTetrahedron = kNodesPerTetrahedron * 24 + 16 + 0.1 * 12;

bool has_damage(const v1::RunSpec& spec) {
  return spec.has_damage() && spec.damage().model() != v1::NONE &&
         spec.damage().model() != v1::DAMAGE_MODEL_UNSPECIFIED;
}

// The damage's memory (0 without it): per element, and in 3-D the direct solver's factor.
double damage_bytes(const v1::RunSpec& spec, double elements, double nodes, int dim) {
  if (!has_damage(spec)) return 0;
  double bytes = kDamageBytesPerElement * elements;
  const auto solver = spec.damage().linear_solver();
  const bool direct =
      solver == v1::DIRECT || (solver != v1::ITERATIVE && nodes <= damage::direct_max_nodes(dim));
  if (dim == 3 && direct)
    bytes += kDamageFactorBytes3d * std::pow(nodes / kDamageFactorNodes3d, 2.5);
  return bytes;
}

}  // namespace

double spec_area_m2(const v1::RunSpec& spec) {
  const auto& g = spec.geometry();
  if (g.has_disk()) return std::numbers::pi * g.disk().radius() * g.disk().radius();
  if (g.has_rounded_square()) {
    const double side = g.rounded_square().side(), r = g.rounded_square().corner_radius();
    return side * side - (4.0 - std::numbers::pi) * r * r;
  }
  if (g.has_corrugated_strip()) {  // the corrugation's mean over the half wavelength is zero
    return 0.5 * g.corrugated_strip().wavelength() * g.corrugated_strip().height();
  }
  return std::nan("");
}

double spec_volume_m3(const v1::RunSpec& spec) {
  const auto& g = spec.geometry();
  if (g.has_cylinder()) {
    const double r = g.cylinder().radius();
    return std::numbers::pi * r * r * g.cylinder().thickness();
  }
  if (g.has_corrugated_box()) {  // the corrugation's mean is zero for kx, ky > 0; a flat box else
    const auto& b = g.corrugated_box();
    const double mean_top = b.kx() == 0 && b.ky() == 0 ? b.amplitude() : 0.0;
    return b.lx() * b.ly() * (b.lz() + mean_top);
  }
  return std::nan("");
}

namespace {

// The stable step for a smallest element altitude `altitude` (uncompressed) at the load.
double stable_dt_at_load(const v1::RunSpec& spec, double altitude0, double mass_factor) {
  const auto& m = spec.material();
  const double kappa = m.bulk_modulus(), n = m.tait_gamma() + 1.0;
  const double pressure = std::max(0.0, spec.load().pressure());
  // The Tait state at the load's pressure, p = (kappa / n)(J^-n - 1), and its wave speed: the
  // solver's own laws (continuum.hpp).
  const double j_minus_n = 1.0 + n * pressure / kappa;
  const double j = std::pow(j_minus_n, -1.0 / n);
  const double bulk = continuum::tait_bulk_modulus(kappa, j_minus_n);
  const double c_sq = continuum::longitudinal_speed_sq(bulk, m.shear_modulus(), m.density(), j);
  const double c = std::sqrt(c_sq);
  const double altitude = altitude0 * j;
  const double h = 0.2 * altitude;
  // The viscous term of the solver's step, h / (q + sqrt(q^2 + c^2)) (continuum::stable_step_sq):
  // the artificial viscosity inside a shock front, where the compression measure z (velocity
  // jump across an element over the sound speed) stays below ~0.5, gives q ~ c (c2 + c1 z); the
  // physical one q = 4/3 eta J / (rho0 h), on the typical element (the fifth above is for the
  // acoustic limit of a graded mesh's smallest element).
  const double q = c * (spec.viscosity().c2() + 0.5 * spec.viscosity().c1()) +
                   4.0 / 3.0 * m.shear_viscosity() * j / (m.density() * altitude);
  // h / (q + sqrt(q^2 + c^2)), the damped oscillator's limit, with the kinematic viscosity q h.
  return spec.run().cfl() * mass_factor *
         std::sqrt(continuum::stable_step_sq_kinematic(h * h, c_sq, q * h));
}

}  // namespace

double estimate_stable_dt(const v1::RunSpec& spec, double elements, double area_m2) {
  // Equilateral triangle of area a: altitude sqrt(sqrt(3) a); the smallest of a graded mesh
  // is taken as a fifth of that (checked against the solver: tests/server/test_admission.cpp).
  const double mean_area = area_m2 / std::max(1.0, elements);
  return stable_dt_at_load(spec, std::sqrt(std::sqrt(3.0) * mean_area),
                           mass_blend_step_factor(spec.element().mass_blend()));
}

double estimate_stable_dt_3d(const v1::RunSpec& spec, double elements, double volume_m3) {
  const double mean_volume = volume_m3 / std::max(1.0, elements);
  return stable_dt_at_load(spec, continuum::regular_tetrahedron_altitude(mean_volume),
                           1.0 / std::sqrt(1.0 + 0.8 * spec.element().mass_blend()));
}

ResourceEstimate estimate_resources(const v1::RunSpec& spec, double elements, double area_m2) {
  const auto& r = spec.run();
  ResourceEstimate e;
  e.dt_s = estimate_stable_dt(spec, elements, area_m2);
  e.steps = r.end_time() / e.dt_s;
  const double samples = std::floor(r.end_time() / r.history_interval()) + 1;
  const double history_bytes = samples * (kHistoryColumns + r.modes() + 1) * 8;
  const double frames =
      r.output_interval() > 0 ? std::floor(r.end_time() / r.output_interval()) + 1 : 0;
  // The history is kept while running and copied once when the file is finished.
  e.memory_bytes = kFixedBytes + kBytesPerElement * elements + 2 * history_bytes +
                   kFrameBytesPerElement * elements + damage_bytes(spec, elements, elements / 2, 2);
  e.disk_bytes = frames * (kFrameBytesPerElement * elements + kFrameOverheadBytes) + history_bytes +
                 kMeshBytesPerElement * elements;
  return e;
}

ResourceEstimate estimate_resources_3d(const v1::RunSpec& spec, double elements, double volume_m3) {
  const auto& r = spec.run();
  ResourceEstimate e;
  e.dt_s = estimate_stable_dt_3d(spec, elements, volume_m3);
  e.steps = r.end_time() / e.dt_s;
  const double samples = std::floor(r.end_time() / r.history_interval()) + 1;
  // The modes twice: at the mid-plane and averaged over the thickness.
  const double history_bytes = samples * (kHistoryColumns + 2 * (r.modes() + 1)) * 8;
  const double frames =
      r.output_interval() > 0 ? std::floor(r.end_time() / r.output_interval()) + 1 : 0;
  const double fixed = !spec.geometry().mesh_file().empty() || !spec.geometry().mesh_id().empty()
                           ? kFixedBytes3dWithGmsh
                           : kFixedBytes3d;
  e.memory_bytes = fixed + kBytesPerTetrahedron * elements + 2 * history_bytes +
                   kFrameBytesPerTetrahedron * elements +
                   damage_bytes(spec, elements, kNodesPerTetrahedron * elements, 3);
  e.disk_bytes = frames * (kFrameBytesPerTetrahedron * elements + kFrameOverheadBytes) +
                 history_bytes + kMeshBytesPerTetrahedron * elements;
  return e;
}

ResourceEstimate estimate_spec_resources(const v1::RunSpec& spec) {
  const double elements = spec.geometry().target_elements();
  const double volume = spec_volume_m3(spec);
  if (!std::isnan(volume)) return estimate_resources_3d(spec, elements, volume);
  const double area = spec_area_m2(spec);
  if (!std::isnan(area)) return estimate_resources(spec, elements, area);
  const double nan = std::nan("");
  return {nan, nan, nan, nan};
}

ResourceEstimate estimate_mesh_resources(const v1::RunSpec& spec, const Mesh& mesh) {
  const double elements = static_cast<double>(mesh.element_count());
  return mesh.dimension() == 3 ? estimate_resources_3d(spec, elements, mesh_volume(mesh))
                               : estimate_resources(spec, elements, mesh_area(mesh));
}

}  // namespace softshock
