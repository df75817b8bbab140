#include "run_summary.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sstream>

namespace softshock {
namespace {

// Vertex of the parabola through three equally spaced samples around index k.
double refine_extremum(const std::vector<double>& t, const std::vector<double>& v, std::size_t k) {
  if (k == 0 || k + 1 >= v.size()) return t[k];
  const double d = v[k - 1] - 2 * v[k] + v[k + 1];
  if (d == 0) return t[k];
  const double shift = 0.5 * (v[k - 1] - v[k + 1]) / d;
  const double h = 0.5 * (t[k + 1] - t[k - 1]);
  return t[k] + std::clamp(shift, -0.5, 0.5) * h;
}

}  // namespace

NondimensionalGroups nondimensional_groups(const Material& material,
                                           const ArtificialViscosity& viscosity,
                                           const PressurePulse& load, double r0) {
  const double c0 = std::sqrt(material.bulk_modulus_Pa / material.density_kg_m3);
  NondimensionalGroups g;
  g.time_scale_s = r0 / c0;
  g.pbar = load.pressure_Pa / material.bulk_modulus_Pa;
  g.tbar_pulse = load.duration_s / g.time_scale_s;
  g.mubar = material.shear_modulus_Pa / material.bulk_modulus_Pa;
  g.gamma = material.tait_gamma;
  g.c1 = viscosity.c1;
  g.c2 = viscosity.c2;
  return g;
}

NondimensionalGroups nondimensional_groups(const Problem& p) {
  return nondimensional_groups(p.material, p.viscosity, p.load, polar_frame(p).reference_radius_m);
}

RunSummary summarize(const Problem& problem, const RunResult& r) {
  RunSummary s;
  s.kernel_time_s = r.kernel_time_s;
  s.diagnostics_time_s = r.diagnostics_time_s;
  s.output_time_s = r.output_time_s;
  const History& h = r.history;
  s.elements = problem.mesh.element_count();
  s.nodes = problem.mesh.node_count();
  s.steps = r.steps;
  s.wall_time_s = r.wall_time_s;
  s.groups = nondimensional_groups(problem);
  s.min_dt_s = r.min_dt_s, s.max_dt_s = r.max_dt_s;
  s.status = r.status == RunStatus::kCompleted   ? "completed"
             : r.status == RunStatus::kCancelled ? "cancelled"
                                                 : "failed";
  s.error = r.error;
  s.failure = failure_name(r.failure);
  // 3-D energies are the body's (J); the summary's are per metre along z.
  double per_metre = 1.0;
  if (problem.mesh.dimension() == 3) {
    const auto [lo, hi] = std::minmax_element(problem.mesh.z.begin(), problem.mesh.z.end());
    s.dimension = 3;
    s.thickness_m = *hi - *lo;
    per_metre = 1.0 / s.thickness_m;
  }
  const std::size_t n = h.size();
  if (n == 0) return s;
  s.end_time_s = h.time.back();
  s.energy_injected_J_per_m = per_metre * h.external_work.back();

  const double pulse_end = problem.load.end_s();
  const double first_cycle_end = 4.0 * s.groups.time_scale_s;
  bool after_pulse_found = false;
  double center_min = 0;
  s.abar_end = h.abar.back();
  s.abar_filtered_end = h.abar_filtered.back();
  for (std::size_t k = 0; k < n; ++k) {
    s.max_abar = std::max(s.max_abar, h.abar[k]);
    s.max_abar_filtered = std::max(s.max_abar_filtered, h.abar_filtered[k]);
    s.max_aspect_ratio = std::max(s.max_aspect_ratio, h.max_aspect_ratio[k]);
    if (s.aspect_ratio_above_10_s < 0 && h.max_aspect_ratio[k] > 10)
      s.aspect_ratio_above_10_s = h.time[k];
    if (h.time[k] <= first_cycle_end * (1 + 1e-12)) {
      s.max_abar_first_cycle = std::max(s.max_abar_first_cycle, h.abar[k]);
      s.max_abar_filtered_first_cycle =
          std::max(s.max_abar_filtered_first_cycle, h.abar_filtered[k]);
      center_min = std::min(center_min, h.center_mean_stress[k]);
    }
    if (!after_pulse_found && h.time[k] >= pulse_end * (1 - 1e-12)) {
      s.energy_after_pulse_J_per_m = per_metre * (h.kinetic_energy[k] + h.elastic_energy[k]);
      after_pulse_found = true;
    }
  }

  // Phase-field damage: the damaged zone's onset and its largest size.
  if (h.damage && h.damaged_volume.size() == n) {
    s.damage = true;
    s.damage_time_s = r.damage_time_s;
    s.damage_solves = r.damage_solves;
    for (std::size_t k = 0; k < n; ++k) {
      if (s.damage_onset_s < 0 && h.damaged_volume[k] > 0) s.damage_onset_s = h.time[k];
      s.max_damaged_volume = std::max(s.max_damaged_volume, h.damaged_volume[k]);
    }
    s.max_damaged_radius_m = std::sqrt(per_metre * s.max_damaged_volume / std::numbers::pi);
    s.damage_dissipation_J_per_m = per_metre * h.damage_dissipation.back();
    s.crack_energy_J_per_m = per_metre * h.crack_energy.back();
  }

  // Dominant rim mode at the end: the largest amplitude among modes >= 2 (0 is the uniform
  // expansion, 1 a rigid shift).
  const auto& last = h.modes.back();
  for (std::size_t m = 2; m < last.size(); ++m)
    if (s.dominant_mode_end < 2 || last[m] > last[s.dominant_mode_end])
      s.dominant_mode_end = static_cast<int>(m);

  // Shock at the centre: the first compressive peak of the centre's mean stress, i.e. the
  // first local minimum after it falls below half its first-cycle minimum.
  if (center_min < 0) {
    std::size_t k = 0;
    while (k < n && h.center_mean_stress[k] > 0.5 * center_min) ++k;
    while (k + 1 < n && h.center_mean_stress[k + 1] < h.center_mean_stress[k]) ++k;
    if (k < n) s.shock_at_center_s = refine_extremum(h.time, h.center_mean_stress, k);
  }

  // Rim reflections: peaks of the rim's mean outward radial acceleration after the shock has
  // reached the centre, at least a quarter of the largest such peak.
  const double t_from = std::max(pulse_end, s.shock_at_center_s);
  double a_max = 0;
  for (std::size_t k = 0; k < n; ++k)
    if (h.time[k] > t_from) a_max = std::max(a_max, h.rim_mean_radial_acceleration[k]);
  const auto& a = h.rim_mean_radial_acceleration;
  for (std::size_t k = 1; k + 1 < n && a_max > 0; ++k) {
    if (h.time[k] <= t_from) continue;
    if (a[k] >= 0.25 * a_max && a[k] >= a[k - 1] && a[k] > a[k + 1])
      s.rim_reflections_s.push_back(refine_extremum(h.time, a, k));
  }
  return s;
}

}  // namespace softshock
