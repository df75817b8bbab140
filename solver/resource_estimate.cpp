#include "solver/resource_estimate.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "solver/continuum.hpp"
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

}  // namespace

double spec_area_m2(const v1::RunSpec& spec) {
  const auto& g = spec.geometry();
  if (g.has_disk()) return std::numbers::pi * g.disk().radius() * g.disk().radius();
  if (g.has_rounded_square()) {
    const double side = g.rounded_square().side(), r = g.rounded_square().corner_radius();
    return side * side - (4.0 - std::numbers::pi) * r * r;
  }
  return std::nan("");
}

double estimate_stable_dt(const v1::RunSpec& spec, double elements, double area_m2) {
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
  // Equilateral triangle of area a: altitude sqrt(sqrt(3) a); the smallest of a graded mesh
  // is taken as a fifth of that (checked against the solver: tests/server/test_admission.cpp).
  const double mean_area = area_m2 / std::max(1.0, elements);
  const double altitude = std::sqrt(std::sqrt(3.0) * mean_area) * j;
  const double h = 0.2 * altitude;
  // The viscous term of the solver's step, h / (q + sqrt(q^2 + c^2)) (continuum::stable_step_sq):
  // the artificial viscosity inside a shock front, where the compression measure z (velocity
  // jump across an element over the sound speed) stays below ~0.5, gives q ~ c (c2 + c1 z); the
  // physical one q = 4/3 eta J / (rho0 h), on the typical element (the fifth above is for the
  // acoustic limit of a graded mesh's smallest element).
  const double q = c * (spec.viscosity().c2() + 0.5 * spec.viscosity().c1()) +
                   4.0 / 3.0 * m.shear_viscosity() * j / (m.density() * altitude);
  // h / (q + sqrt(q^2 + c^2)), the damped oscillator's limit, with the kinematic viscosity q h.
  return spec.run().cfl() * mass_blend_step_factor(spec.element().mass_blend()) *
         std::sqrt(continuum::stable_step_sq_kinematic(h * h, c_sq, q * h));
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
                   kFrameBytesPerElement * elements;
  e.disk_bytes = frames * (kFrameBytesPerElement * elements + kFrameOverheadBytes) + history_bytes +
                 kMeshBytesPerElement * elements;
  return e;
}

}  // namespace softshock
