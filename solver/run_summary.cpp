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

std::string number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
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

double RunSummary::grind_ns() const {
  const double element_steps = static_cast<double>(steps) * static_cast<double>(elements);
  return element_steps > 0 ? wall_time_s / element_steps * 1e9 : std::nan("");
}

double RunSummary::kernel_grind_ns() const {
  const double element_steps = static_cast<double>(steps) * static_cast<double>(elements);
  return element_steps > 0 ? kernel_time_s / element_steps * 1e9 : std::nan("");
}

double RunSummary::meshing_share() const {
  const double total = meshing_time_s + wall_time_s;
  return total > 0 ? meshing_time_s / total : std::nan("");
}

double RunSummary::diagnostics_share() const {
  return wall_time_s > 0 ? diagnostics_time_s / wall_time_s : std::nan("");
}

double RunSummary::output_share() const {
  return wall_time_s > 0 ? output_time_s / wall_time_s : std::nan("");
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

const std::vector<std::pair<std::string, std::string>>& renamed_summary_names() {
  static const std::vector<std::pair<std::string, std::string>> names = {
      {"wall_time", "wall_time_s"},
      {"end_time", "end_time_s"},
      {"time_scale", "time_scale_s"},
      {"energy_injected", "energy_injected_J_per_m"},
      {"energy_after_pulse", "energy_after_pulse_J_per_m"},
      {"shock_at_center", "shock_at_center_s"},
      {"rim_reflections", "rim_reflections_s"},
      {"min_dt", "min_dt_s"},
      {"max_dt", "max_dt_s"},
      {"kernel_time", "kernel_time_s"},
      {"grind_time", "grind_ns"},
      {"kernel_grind_time", "kernel_grind_ns"},
      {"meshing_time", "meshing_time_s"},
      {"aspect_ratio_above_10", "aspect_ratio_above_10_s"},
      {"diagnostics_time", "diagnostics_time_s"},
      {"output_time", "output_time_s"},
  };
  return names;
}

std::string current_summary_name(const std::string& name) {
  for (const auto& [old_name, name_now] : renamed_summary_names()) {
    if (name == old_name) return name_now;
  }
  return name;
}

std::string summary_to_json(const RunSummary& s) {
  std::ostringstream o;
  o << "{\"status\":\"" << s.status << "\"";
  if (!s.error.empty()) {
    std::string e;
    for (char c : s.error) {
      if (c == '"' || c == '\\') e += '\\';
      if (static_cast<unsigned char>(c) >= 0x20) e += c;
    }
    o << ",\"error\":\"" << e << "\"";
  }
  if (!s.failure.empty()) o << ",\"failure\":\"" << s.failure << "\"";
  o << ",\"solver_revision\":" << s.solver_revision;
  if (s.dimension == 3) o << ",\"dimension\":3,\"thickness_m\":" << number(s.thickness_m);
  o << ",\"elements\":" << s.elements << ",\"nodes\":" << s.nodes << ",\"steps\":" << s.steps
    << ",\"wall_time_s\":" << number(s.wall_time_s) << ",\"end_time_s\":" << number(s.end_time_s)
    << ",\"groups\":{\"pbar\":" << number(s.groups.pbar)
    << ",\"tbar_pulse\":" << number(s.groups.tbar_pulse) << ",\"mubar\":" << number(s.groups.mubar)
    << ",\"gamma\":" << number(s.groups.gamma) << ",\"c1\":" << number(s.groups.c1)
    << ",\"c2\":" << number(s.groups.c2) << ",\"time_scale_s\":" << number(s.groups.time_scale_s)
    << "},\"energy_injected_J_per_m\":" << number(s.energy_injected_J_per_m)
    << ",\"energy_after_pulse_J_per_m\":" << number(s.energy_after_pulse_J_per_m)
    << ",\"max_abar_first_cycle\":" << number(s.max_abar_first_cycle)
    << ",\"max_abar\":" << number(s.max_abar) << ",\"abar_end\":" << number(s.abar_end)
    << ",\"max_abar_filtered_first_cycle\":" << number(s.max_abar_filtered_first_cycle)
    << ",\"max_abar_filtered\":" << number(s.max_abar_filtered)
    << ",\"abar_filtered_end\":" << number(s.abar_filtered_end)
    << ",\"max_aspect_ratio\":" << number(s.max_aspect_ratio)
    << ",\"aspect_ratio_above_10_s\":" << number(s.aspect_ratio_above_10_s)
    << ",\"dominant_mode_end\":" << s.dominant_mode_end
    << ",\"shock_at_center_s\":" << number(s.shock_at_center_s) << ",\"rim_reflections_s\":[";
  for (std::size_t k = 0; k < s.rim_reflections_s.size(); ++k)
    o << (k ? "," : "") << number(s.rim_reflections_s[k]);
  o << "],\"min_dt_s\":" << number(s.min_dt_s) << ",\"max_dt_s\":" << number(s.max_dt_s)
    << ",\"kernel_time_s\":" << number(s.kernel_time_s) << ",\"grind_ns\":" << number(s.grind_ns())
    << ",\"kernel_grind_ns\":" << number(s.kernel_grind_ns())
    << ",\"diagnostics_time_s\":" << number(s.diagnostics_time_s)
    << ",\"diagnostics_share\":" << number(s.diagnostics_share())
    << ",\"output_time_s\":" << number(s.output_time_s)
    << ",\"output_share\":" << number(s.output_share())
    << ",\"meshing_time_s\":" << number(s.meshing_time_s)
    << ",\"meshing_share\":" << number(s.meshing_share()) << ",\"mesh_cache\":\"" << s.mesh_cache
    << "\"";
  if (s.damage)
    o << ",\"damage_onset_s\":" << number(s.damage_onset_s)
      << ",\"max_damaged_volume\":" << number(s.max_damaged_volume)
      << ",\"max_damaged_radius_m\":" << number(s.max_damaged_radius_m)
      << ",\"damage_dissipation_J_per_m\":" << number(s.damage_dissipation_J_per_m)
      << ",\"crack_energy_J_per_m\":" << number(s.crack_energy_J_per_m)
      << ",\"damage_time_s\":" << number(s.damage_time_s)
      << ",\"damage_solves\":" << s.damage_solves;
  o << "}";
  return o.str();
}

}  // namespace softshock
