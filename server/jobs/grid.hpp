// Parameter grids: a base spec swept over one to three axes (docs/api.md, "Grids"). An axis
// names a numeric spec field or a nondimensional group of physics.md section 7; its values are
// a list, a linspace or a geomspace. Expansion validates everything up front so a grid is
// accepted whole or not at all, and canonicalises every point so identical runs hash equal.
#pragma once

#include <string>
#include <vector>

#include "server/store/catalogue.hpp"
#include "softshock/v1/service.pb.h"
#include "solver/run_spec.hpp"
#include "solver/summary_figures.hpp"

namespace softshock::server {

inline constexpr int kMaxGridAxes = 3;
inline constexpr int kMaxAxisPoints = 1000;
inline constexpr int kMaxGridPoints = 10000;

// The groups an axis may name, in the order physics.md lists them.
const std::vector<std::string>& grid_group_names();

// The values of an axis (list, linspace or geomspace), validated. `field` is the axis' path in
// the request for error messages ("axes[0]"). Throws SpecError.
std::vector<double> axis_values(const v1::GridAxis& axis, const std::string& field);

// Sets one grid coordinate on a spec: a group (pbar, tbar_pulse, mubar, gamma, c1, c2; any
// case) maps onto its dimensional field with the spec's own kappa, rho0 and R0
// (P = pbar kappa, t_pulse = tbar_pulse R0 / sqrt(kappa / rho0), mu = mubar kappa); anything
// else is a numeric spec field path. Throws SpecError naming `field`.
void apply_grid_value(v1::RunSpec& spec, const std::string& name, double value,
                      const std::string& field = "axes");

// Rounds every floating-point field to 12 significant digits, so values that differ only by
// the rounding of how they were computed (0.7 * 2e9 vs 1.4e9) become the same spec and hash.
void canonicalize_spec(v1::RunSpec& spec);

// A normalized, canonical spec and its hash (SHA-256 of the canonical JSON).
struct CanonicalSpec {
  v1::RunSpec spec;
  std::string json, hash;
};
// Defaults, canonical floats, validation: what every job is stored as. Throws SpecError.
CanonicalSpec canonical_spec(const v1::RunSpec& spec, const SpecLimits& limits);

struct GridPlan {
  std::vector<v1::GridAxis> axes;  // name + expanded values
  std::vector<int> shape;
  std::vector<CanonicalSpec> points;  // row-major, last axis fastest
};

// Expands base x axes into the grid's points. Throws SpecError naming the offending field:
// axis count, unknown or repeated names, empty/too many/non-finite/repeated values, total
// points, and any point whose spec breaks a rule (e.g. "axes[0]: pbar = 300 gives
// load.pressure: must be ...").
GridPlan expand_grid(const v1::RunSpec& base,
                     const google::protobuf::RepeatedPtrField<v1::GridAxis>& axes,
                     const SpecLimits& limits);

// The scalars a grid reduces to, with units. The first is the default.
struct GridQuantity {
  const char* name;
  const char* units;
  bool needs_tbar;
  const SummaryFigure* figure;  // the summary figure it reads; nullptr for abar_at
};
const std::vector<GridQuantity>& grid_quantities();
// By name; a summary figure's older name (energy_injected, ...) finds today's quantity.
const GridQuantity* find_grid_quantity(const std::string& name);

// One point's value of a quantity from its catalogued summary; NaN where undefined (A-bar at a
// t-bar outside the run). A-bar at t-bar interpolates the stored samples linearly.
double grid_quantity(const GridQuantity& quantity, const StoredSummary& stored, double tbar);

}  // namespace softshock::server
