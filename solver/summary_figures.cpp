#include "summary_figures.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <type_traits>

namespace softshock {
namespace {

// A JSON string's contents: quotes and backslashes escaped, control characters dropped.
std::string json_escaped(const std::string& text) {
  std::string e;
  for (char c : text) {
    if (c == '"' || c == '\\') e += '\\';
    if (static_cast<unsigned char>(c) >= 0x20) e += c;
  }
  return e;
}

std::string number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

struct Row {
  const char* name;
  const char* former;
  const char* column;
  const char* unit;
  const char* meaning;
  unsigned traits;
};

SummaryFigure make(const Row& r, FigureType type) {
  return {r.name, r.former, r.column, r.unit, r.meaning, type, r.traits};
}

template <auto... Path>
SummaryFigure real(const Row& r) {
  SummaryFigure f = make(r, FigureType::kReal);
  f.get = [](const RunSummary& s) { return static_cast<double>(member_at<Path...>(s)); };
  f.set = [](RunSummary& s, double v) { member_at<Path...>(s) = v; };
  return f;
}

// An integer: anything but a finite value in 0..2^53 reads as 0 (converting NaN, a negative or
// an out-of-range double to an integer type is undefined behaviour).
template <auto... Path>
SummaryFigure integer(const Row& r) {
  SummaryFigure f = make(r, FigureType::kInteger);
  f.get = [](const RunSummary& s) { return static_cast<double>(member_at<Path...>(s)); };
  f.set = [](RunSummary& s, double v) {
    using Int = std::remove_reference_t<decltype(member_at<Path...>(s))>;
    constexpr double kExact = 9007199254740992.0;  // 2^53: every integer below is exact
    const double hi = std::min(kExact, static_cast<double>(std::numeric_limits<Int>::max()));
    member_at<Path...>(s) = std::isfinite(v) && v >= 0 && v <= hi ? static_cast<Int>(v) : Int{0};
  };
  return f;
}

template <auto... Path>
SummaryFigure flag(const Row& r) {
  SummaryFigure f = make(r, FigureType::kFlag);
  f.get = [](const RunSummary& s) { return member_at<Path...>(s) ? 1.0 : 0.0; };
  f.set = [](RunSummary& s, double v) { member_at<Path...>(s) = v != 0 && !std::isnan(v); };
  return f;
}

template <auto... Path>
SummaryFigure text(const Row& r) {
  SummaryFigure f = make(r, FigureType::kText);
  f.text = [](const RunSummary& s) -> const std::string& { return member_at<Path...>(s); };
  f.text_ref = [](RunSummary& s) -> std::string& { return member_at<Path...>(s); };
  return f;
}

template <auto... Path>
SummaryFigure series(const Row& r) {
  SummaryFigure f = make(r, FigureType::kSeries);
  f.series = [](const RunSummary& s) -> const std::vector<double>& {
    return member_at<Path...>(s);
  };
  f.series_ref = [](RunSummary& s) -> std::vector<double>& { return member_at<Path...>(s); };
  return f;
}

template <double (RunSummary::*Method)() const>
SummaryFigure derived(const Row& r) {
  SummaryFigure f = make(r, FigureType::kReal);
  f.get = [](const RunSummary& s) { return (s.*Method)(); };
  return f;
}

using RS = RunSummary;
using G = NondimensionalGroups;

constexpr unsigned kQG = kQueryable | kGridQuantity;

const std::vector<SummaryFigure>& table() {
  static const std::vector<SummaryFigure> figures = {
      text<&RS::status>(
          {"status", nullptr, "status", "", "completed, cancelled or failed", kNotInJobSummary}),
      text<&RS::error>(
          {"error", nullptr, "error", "", "why the run failed", kOnlyNonEmpty | kNotInJobSummary}),
      text<&RS::failure>({"failure", nullptr, nullptr, "",
                          "a failed run's cause (MESH_DISTORTION, ...); the job's error reports it",
                          kOnlyNonEmpty | kNotInJobSummary}),
      integer<&RS::solver_revision>({"solver_revision", nullptr, "solver_revision", "1",
                                     "the solver's numerics revision (0: not recorded)",
                                     kOptional}),
      integer<&RS::dimension>({"dimension", nullptr, "dimension", "1",
                               "2: plane strain per metre of thickness; 3: tetrahedra",
                               kOnly3D | kOptional}),
      real<&RS::thickness_m>({"thickness_m", nullptr, "thickness", "m",
                              "3-D: the z extent the per-metre figures divide by",
                              kOnly3D | kOptional}),
      integer<&RS::elements>({"elements", nullptr, "elements", "1", "elements", kQueryable}),
      integer<&RS::nodes>({"nodes", nullptr, "nodes", "1", "nodes", 0}),
      integer<&RS::steps>({"steps", nullptr, "steps", "1", "time steps", kQueryable}),
      real<&RS::wall_time_s>(
          {"wall_time_s", "wall_time", "wall_time", "s", "the run's wall time", kQG}),
      real<&RS::end_time_s>({"end_time_s", "end_time", "end_time", "s", "simulated time", 0}),
      real<&RS::groups, &G::pbar>(
          {"pbar", nullptr, "pbar", "1", "P-bar = P / kappa", kInGroups | kQueryable}),
      real<&RS::groups, &G::tbar_pulse>({"tbar_pulse", nullptr, "tbar_pulse", "1",
                                         "the pulse's duration over the time scale",
                                         kInGroups | kQueryable}),
      real<&RS::groups, &G::mubar>(
          {"mubar", nullptr, "mubar", "1", "mu-bar = mu / kappa", kInGroups | kQueryable}),
      real<&RS::groups, &G::gamma>(
          {"gamma", nullptr, "gamma", "1", "Tait's exponent n", kInGroups | kQueryable}),
      real<&RS::groups, &G::c1>(
          {"c1", nullptr, "c1", "1", "linear viscosity coefficient", kInGroups | kQueryable}),
      real<&RS::groups, &G::c2>(
          {"c2", nullptr, "c2", "1", "quadratic viscosity coefficient", kInGroups | kQueryable}),
      real<&RS::groups, &G::time_scale_s>(
          {"time_scale_s", "time_scale", "time_scale", "s", "R0 / sqrt(kappa / rho0)", kInGroups}),
      real<&RS::energy_injected_J_per_m>({"energy_injected_J_per_m", "energy_injected",
                                          "energy_injected", "J/m",
                                          "external work at the end of the run", kQG}),
      real<&RS::energy_after_pulse_J_per_m>({"energy_after_pulse_J_per_m", "energy_after_pulse",
                                             "energy_after_pulse", "J/m",
                                             "kinetic + elastic when the pulse has ended", kQG}),
      real<&RS::max_abar_first_cycle>({"max_abar_first_cycle", nullptr, "max_abar_first_cycle", "1",
                                       "max A-bar over 0 <= t-bar <= 4", kQG}),
      real<&RS::max_abar>(
          {"max_abar", nullptr, "max_abar", "1", "max A-bar over the whole run", kQG}),
      real<&RS::abar_end>(
          {"abar_end", nullptr, "abar_end", "1", "A-bar at the end", kOptional | kGridQuantity}),
      real<&RS::max_abar_filtered_first_cycle>(
          {"max_abar_filtered_first_cycle", nullptr, "max_abar_filtered_first_cycle", "1",
           "max filtered A-bar (modes 0..32) over 0 <= t-bar <= 4", kOptional | kGridQuantity}),
      real<&RS::max_abar_filtered>({"max_abar_filtered", nullptr, "max_abar_filtered", "1",
                                    "max filtered A-bar over the whole run",
                                    kOptional | kGridQuantity}),
      real<&RS::abar_filtered_end>({"abar_filtered_end", nullptr, "abar_filtered_end", "1",
                                    "filtered A-bar at the end", kOptional | kGridQuantity}),
      real<&RS::max_aspect_ratio>({"max_aspect_ratio", nullptr, "max_aspect_ratio", "1",
                                   "largest element aspect ratio", kOptional | kGridQuantity}),
      real<&RS::aspect_ratio_above_10_s>(
          {"aspect_ratio_above_10_s", "aspect_ratio_above_10", "aspect_ratio_above_10", "s",
           "first sample with an element above aspect ratio 10 (negative: never)",
           kOptional | kNegativeIsNone}),
      integer<&RS::dominant_mode_end>({"dominant_mode_end", nullptr, "dominant_mode_end", "1",
                                       "largest-amplitude rim mode >= 2 at the end", kQG}),
      real<&RS::shock_at_center_s>({"shock_at_center_s", "shock_at_center", "shock_at_center", "s",
                                    "the shock's arrival at the centre (negative: none)",
                                    kQG | kNegativeIsNone}),
      series<&RS::rim_reflections_s>({"rim_reflections_s", "rim_reflections", "rim_reflections",
                                      "s", "peaks of the rim's outward acceleration", kOptional}),
      real<&RS::min_dt_s>({"min_dt_s", "min_dt", "min_dt", "s", "smallest time step", 0}),
      real<&RS::max_dt_s>({"max_dt_s", "max_dt", "max_dt", "s", "largest time step", 0}),
      real<&RS::kernel_time_s>({"kernel_time_s", "kernel_time", "kernel_time", "s",
                                "wall time of the element passes", kOptional}),
      derived<&RS::grind_ns>(
          {"grind_ns", "grind_time", nullptr, "ns", "ns per element-step of the run", kDerived}),
      derived<&RS::kernel_grind_ns>({"kernel_grind_ns", "kernel_grind_time", nullptr, "ns",
                                     "ns per element-step of the element passes", kDerived}),
      real<&RS::diagnostics_time_s>({"diagnostics_time_s", "diagnostics_time", "diagnostics_time",
                                     "s", "the solver thread's time in history samples and fields",
                                     kOptional}),
      derived<&RS::diagnostics_share>({"diagnostics_share", nullptr, nullptr, "1",
                                       "diagnostics_time_s / wall_time_s", kDerived}),
      real<&RS::output_time_s>({"output_time_s", "output_time", "output_time", "s",
                                "the solver thread's time handing frames to the writer",
                                kOptional}),
      derived<&RS::output_share>(
          {"output_share", nullptr, nullptr, "1", "output_time_s / wall_time_s", kDerived}),
      real<&RS::meshing_time_s>({"meshing_time_s", "meshing_time", "meshing_time", "s",
                                 "meshing or the mesh cache's look-up", kOptional}),
      derived<&RS::meshing_share>({"meshing_share", nullptr, nullptr, "1",
                                   "meshing_time_s / (meshing_time_s + wall_time_s)", kDerived}),
      text<&RS::mesh_cache>(
          {"mesh_cache", nullptr, "mesh_cache", "", "hit, miss, replaced or not-used", kOptional}),
      flag<&RS::damage>(
          {"damage", nullptr, "damage", "1", "whether the run has phase-field damage", kNotInJson}),
      real<&RS::damage_onset_s>({"damage_onset_s", nullptr, "damage_onset", "s",
                                 "when the damaged zone (d >= 1/2) appears (negative: never)",
                                 kOnlyDamage | kGridQuantity | kNegativeIsNone}),
      real<&RS::max_damaged_volume>(
          {"max_damaged_volume", nullptr, "max_damaged_volume", "m^2 (2-D) or m^3 (3-D)",
           "largest measure of the damaged zone", kOnlyDamage | kGridQuantity}),
      real<&RS::max_damaged_radius_m>({"max_damaged_radius_m", nullptr, "max_damaged_radius", "m",
                                       "radius of a disk of the damaged zone's area",
                                       kOnlyDamage | kGridQuantity}),
      real<&RS::damage_dissipation_J_per_m>(
          {"damage_dissipation_J_per_m", nullptr, "damage_dissipation", "J/m",
           "stored energy the damage released", kOnlyDamage | kGridQuantity}),
      real<&RS::crack_energy_J_per_m>({"crack_energy_J_per_m", nullptr, "crack_energy", "J/m",
                                       "crack energy at the end", kOnlyDamage}),
      real<&RS::damage_time_s>({"damage_time_s", nullptr, "damage_time", "s",
                                "wall time of the damage updates", kOnlyDamage | kOptional}),
      integer<&RS::damage_solves>({"damage_solves", nullptr, "damage_solves", "1",
                                   "the damage updates' solves", kOnlyDamage | kOptional}),
  };
  return figures;
}

}  // namespace

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

bool SummaryFigure::written_for(const RunSummary& s) const {
  if (has(kNotInJson)) return false;
  if (has(kOnly3D) && s.dimension != 3) return false;
  if (has(kOnlyDamage) && !s.damage) return false;
  if (has(kOnlyNonEmpty) && text(s).empty()) return false;
  return true;
}

std::span<const SummaryFigure> summary_figures() {
  return table();
}

const SummaryFigure* find_summary_figure(std::string_view name) {
  for (const auto& f : table()) {
    if (name == f.name || (f.former && name == f.former)) return &f;
  }
  return nullptr;
}

double figure_value(const SummaryFigure& figure, const RunSummary& s) {
  if (!figure.get) return NAN;
  if (figure.has(kOnlyDamage) && !s.damage) return NAN;
  const double v = figure.get(s);
  return figure.has(kNegativeIsNone) && v < 0 ? NAN : v;
}

const std::vector<std::pair<std::string, std::string>>& renamed_summary_names() {
  static const std::vector<std::pair<std::string, std::string>> names = [] {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& f : summary_figures()) {
      if (f.former) out.emplace_back(f.former, f.name);
    }
    return out;
  }();
  return names;
}

std::string current_summary_name(const std::string& name) {
  const SummaryFigure* f = find_summary_figure(name);
  return f ? f->name : name;
}

// The figures of summary_figures() that the run has, in its order; kInGroups ones in "groups".
std::string summary_to_json(const RunSummary& s) {
  std::ostringstream o;
  o << "{";
  const char* separator = "";
  bool in_groups = false;
  for (const auto& f : summary_figures()) {
    if (!f.written_for(s)) continue;
    if (f.has(kInGroups) != in_groups) {
      o << (in_groups ? "}" : std::string(separator) + "\"groups\":{");
      separator = in_groups ? "," : "";
      in_groups = !in_groups;
    }
    o << separator << '"' << f.name << "\":";
    separator = ",";
    switch (f.type) {
      case FigureType::kText:
        o << '"' << json_escaped(f.text(s)) << '"';
        break;
      case FigureType::kSeries: {
        const auto& v = f.series(s);
        o << '[';
        for (std::size_t k = 0; k < v.size(); ++k) o << (k ? "," : "") << number(v[k]);
        o << ']';
        break;
      }
      case FigureType::kInteger:
      case FigureType::kFlag:
        o << static_cast<int64_t>(f.get(s));
        break;
      case FigureType::kReal:
        o << number(f.get(s));
        break;
    }
  }
  if (in_groups) o << "}";
  o << "}";
  return o.str();
}

}  // namespace softshock
