#include "server/jobs/grid.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <sstream>

#include "server/store/spec_hash.hpp"

namespace softshock::server {
namespace {

namespace pb = google::protobuf;

// Each group and the dimensional field it sets.
struct GroupField {
  const char* group;
  const char* field;
};
constexpr GroupField kGroupFields[] = {
    {"pbar", "load.pressure"},
    {"tbar_pulse", "load.duration"},
    {"mubar", "material.shear_modulus"},
    {"gamma", "material.tait_gamma"},
    {"c1", "viscosity.c1"},
    {"c2", "viscosity.c2"},
};

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

const GroupField* find_group(const std::string& name) {
  const std::string key = lower(name);
  for (const auto& g : kGroupFields) {
    if (key == g.group) return &g;
  }
  return nullptr;
}

std::string number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

double round_significant(double v) {
  if (!std::isfinite(v) || v == 0) return v;
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.12g", v);
  return std::strtod(buf, nullptr);
}

// The descriptors along a numeric spec field path ("load.pressure" or "load.pressure" in JSON
// spelling: "geometry.targetElements"). Throws SpecError naming `field`.
std::vector<const pb::FieldDescriptor*> resolve_path(const std::string& path,
                                                     const std::string& field) {
  std::vector<const pb::FieldDescriptor*> out;
  const pb::Descriptor* d = v1::RunSpec::descriptor();
  std::stringstream parts(path);
  std::string part;
  while (std::getline(parts, part, '.')) {
    const pb::FieldDescriptor* f = d ? d->FindFieldByName(part) : nullptr;
    if (!f && d) f = d->FindFieldByCamelcaseName(part);
    if (!f) break;
    out.push_back(f);
    d = f->message_type();
  }
  const bool numeric =
      !out.empty() &&
      out.size() == static_cast<std::size_t>(std::count(path.begin(), path.end(), '.') + 1) &&
      (out.back()->cpp_type() == pb::FieldDescriptor::CPPTYPE_DOUBLE ||
       out.back()->cpp_type() == pb::FieldDescriptor::CPPTYPE_INT32) &&
      !out.back()->is_repeated();
  if (!numeric) {
    std::string groups;
    for (const auto& g : kGroupFields)
      groups += (groups.empty() ? "" : ", ") + std::string(g.group);
    throw SpecError(field + ".name", "'" + path +
                                         "' is neither a numeric spec field (e.g. load.pressure, "
                                         "material.tait_gamma) nor a group (" +
                                         groups + ")");
  }
  return out;
}

// The field an axis sets, spelled with proto names: two axes must not set the same one.
std::string target_of(const std::string& name, const std::string& field) {
  if (const GroupField* g = find_group(name)) return g->field;
  std::string out;
  for (const auto* f : resolve_path(name, field)) out += (out.empty() ? "" : ".") + f->name();
  return out;
}

void set_field(v1::RunSpec& spec, const std::string& path, double value, const std::string& field) {
  const auto descriptors = resolve_path(path, field);
  pb::Message* message = &spec;
  for (const auto* f : descriptors) {
    const pb::Reflection* r = message->GetReflection();
    if (const pb::OneofDescriptor* oneof = f->containing_oneof()) {
      const pb::FieldDescriptor* set = r->GetOneofFieldDescriptor(*message, oneof);
      if (set != nullptr && set != f) {
        throw SpecError(field + ".name", "'" + path + "' does not apply: the base spec's " +
                                             oneof->name() + " is " + set->name());
      }
    }
    if (f != descriptors.back()) {
      message = r->MutableMessage(message, f);
      continue;
    }
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_INT32) {
      if (value != std::floor(value) || std::abs(value) > 2147483647.0) {
        throw SpecError(field + ".values",
                        path + " takes integers; " + number(value) + " is not one");
      }
      r->SetInt32(message, f, static_cast<int32_t>(value));
    } else {
      r->SetDouble(message, f, value);
    }
  }
}

void canonicalize_message(pb::Message& message) {
  const pb::Reflection* r = message.GetReflection();
  std::vector<const pb::FieldDescriptor*> fields;
  r->ListFields(message, &fields);
  for (const auto* f : fields) {
    if (f->is_repeated()) continue;  // RunSpec has no repeated fields
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_DOUBLE) {
      r->SetDouble(&message, f, round_significant(r->GetDouble(message, f)));
    } else if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
      canonicalize_message(*r->MutableMessage(&message, f));
    }
  }
}

}  // namespace

const std::vector<std::string>& grid_group_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const auto& g : kGroupFields) out.emplace_back(g.group);
    return out;
  }();
  return names;
}

std::vector<double> axis_values(const v1::GridAxis& axis, const std::string& field) {
  const int given = (axis.values_size() > 0) + axis.has_linspace() + axis.has_geomspace();
  if (given != 1) {
    throw SpecError(field, "give exactly one of values, linspace or geomspace");
  }
  std::vector<double> out;
  if (axis.values_size() > 0) {
    out.assign(axis.values().begin(), axis.values().end());
  } else {
    const bool geometric = axis.has_geomspace();
    const v1::Span& span = geometric ? axis.geomspace() : axis.linspace();
    const std::string where = field + (geometric ? ".geomspace" : ".linspace");
    if (!std::isfinite(span.start()) || !std::isfinite(span.stop())) {
      throw SpecError(where, "start and stop must be finite");
    }
    if (span.num() < 1 || span.num() > kMaxAxisPoints) {
      throw SpecError(where + ".num", "must be between 1 and " + std::to_string(kMaxAxisPoints));
    }
    if (geometric && (span.start() <= 0 || span.stop() <= 0)) {
      throw SpecError(where, "start and stop must be > 0");
    }
    const int n = span.num();
    for (int i = 0; i < n; ++i) {
      const double f = n == 1 ? 0.0 : static_cast<double>(i) / (n - 1);
      double v = geometric ? span.start() * std::pow(span.stop() / span.start(), f)
                           : span.start() + (span.stop() - span.start()) * f;
      if (i == n - 1 && n > 1) v = span.stop();  // the end exactly, not start + rounding
      out.push_back(v);
    }
  }
  if (out.size() > static_cast<std::size_t>(kMaxAxisPoints)) {
    throw SpecError(field + ".values",
                    "at most " + std::to_string(kMaxAxisPoints) + " values per axis");
  }
  std::set<double> seen;
  for (double& v : out) {
    if (!std::isfinite(v)) throw SpecError(field + ".values", "values must be finite");
    v = round_significant(v);
    if (!seen.insert(v).second) {
      throw SpecError(field + ".values", "repeats " + number(v) + " (points must differ)");
    }
  }
  return out;
}

void apply_grid_value(v1::RunSpec& spec, const std::string& name, double value,
                      const std::string& field) {
  const GroupField* g = find_group(name);
  if (g == nullptr) {
    set_field(spec, name, value, field);
    return;
  }
  const std::string group = g->group;
  const double kappa = spec.material().bulk_modulus();
  if (group == "pbar") {
    spec.mutable_load()->set_pressure(value * kappa);
  } else if (group == "mubar") {
    spec.mutable_material()->set_shear_modulus(value * kappa);
  } else if (group == "tbar_pulse") {
    const double time_scale = spec_groups(spec).time_scale_s;
    if (!std::isfinite(time_scale)) {
      throw SpecError(field + ".name",
                      "tbar_pulse needs a disk or rounded_square base geometry (a mesh file's "
                      "R0 is known only once it is meshed); sweep load.duration instead");
    }
    spec.mutable_load()->set_duration(value * time_scale);
  } else {
    set_field(spec, g->field, value, field);
  }
}

void canonicalize_spec(v1::RunSpec& spec) {
  canonicalize_message(spec);
}

CanonicalSpec canonical_spec(const v1::RunSpec& spec, const SpecLimits& limits) {
  CanonicalSpec out;
  out.spec = with_defaults(spec);
  canonicalize_spec(out.spec);
  validate_spec(out.spec, limits);
  out.json = spec_to_json(out.spec);
  out.hash = sha256_hex(out.json);
  return out;
}

GridPlan expand_grid(const v1::RunSpec& base, const pb::RepeatedPtrField<v1::GridAxis>& axes,
                     const SpecLimits& limits) {
  if (axes.empty() || axes.size() > kMaxGridAxes) {
    throw SpecError("axes", "a grid has 1 to " + std::to_string(kMaxGridAxes) + " axes, not " +
                                std::to_string(axes.size()));
  }
  GridPlan plan;
  std::set<std::string> targets;
  int64_t total = 1;
  for (int a = 0; a < axes.size(); ++a) {
    const std::string field = "axes[" + std::to_string(a) + "]";
    const v1::GridAxis& axis = axes[a];
    if (axis.name().empty()) throw SpecError(field + ".name", "must name a field or a group");
    if (!targets.insert(target_of(axis.name(), field)).second) {
      throw SpecError(field + ".name",
                      "'" + axis.name() + "' sets the same spec field as another axis");
    }
    v1::GridAxis expanded;
    const GroupField* g = find_group(axis.name());
    expanded.set_name(g ? g->group : axis.name());
    const auto values = axis_values(axis, field);
    expanded.mutable_values()->Assign(values.begin(), values.end());
    total *= static_cast<int64_t>(values.size());
    if (total > kMaxGridPoints) {
      throw SpecError(
          "axes", "the grid would have more than " + std::to_string(kMaxGridPoints) + " points");
    }
    plan.shape.push_back(static_cast<int>(values.size()));
    plan.axes.push_back(std::move(expanded));
  }
  // Fields first, then groups: a group is converted with the point's own kappa, rho0 and R0,
  // so its value on the axis is the one the run has even when another axis changes those.
  std::vector<int> order(plan.axes.size());
  for (std::size_t a = 0; a < order.size(); ++a) order[a] = static_cast<int>(a);
  std::stable_partition(order.begin(), order.end(),
                        [&](int a) { return find_group(plan.axes[a].name()) == nullptr; });
  const v1::RunSpec defaults = with_defaults(base);
  plan.points.reserve(static_cast<std::size_t>(total));
  std::vector<int> at(plan.axes.size(), 0);
  for (int64_t i = 0; i < total; ++i) {
    int64_t rest = i;
    for (int a = static_cast<int>(plan.axes.size()) - 1; a >= 0; --a) {
      at[a] = static_cast<int>(rest % plan.shape[a]);
      rest /= plan.shape[a];
    }
    v1::RunSpec point = defaults;
    std::string coordinates;
    for (int a : order) {
      const double v = plan.axes[a].values(at[a]);
      apply_grid_value(point, plan.axes[a].name(), v, "axes[" + std::to_string(a) + "]");
    }
    try {
      plan.points.push_back(canonical_spec(point, limits));
    } catch (const SpecError& e) {
      for (std::size_t a = 0; a < plan.axes.size(); ++a) {
        coordinates += (coordinates.empty() ? "" : ", ") + plan.axes[a].name() + " = " +
                       number(plan.axes[a].values(at[a]));
      }
      throw SpecError("axes",
                      "the point " + coordinates + " gives an invalid spec: spec." + e.what());
    }
  }
  return plan;
}

const std::vector<GridQuantity>& grid_quantities() {
  static const std::vector<GridQuantity> quantities = [] {
    // The default first, then summary_figures()' other grid quantities and A-bar at a t-bar.
    const SummaryFigure* first = find_summary_figure("max_abar_first_cycle");
    std::vector<GridQuantity> out = {{first->name, first->unit, false, first}};
    for (const auto& f : summary_figures()) {
      if (f.has(kGridQuantity) && &f != first) out.push_back({f.name, f.unit, false, &f});
    }
    out.push_back({"abar_at", "1", true, nullptr});
    return out;
  }();
  return quantities;
}

const GridQuantity* find_grid_quantity(const std::string& name) {
  const std::string current = current_summary_name(name);  // energy_injected, ... still work
  for (const auto& q : grid_quantities()) {
    if (current == q.name) return &q;
  }
  return nullptr;
}

double grid_quantity(const GridQuantity& quantity, const StoredSummary& stored, double tbar) {
  const RunSummary& s = stored.summary;
  // A figure: NaN where the run has none (no damage, a shock never detected).
  if (quantity.figure) return figure_value(*quantity.figure, s);
  // abar_at
  const auto& t = stored.abar_times;
  const auto& a = stored.abar_values;
  const double time = tbar * s.groups.time_scale_s;
  if (t.empty() || t.size() != a.size() || !std::isfinite(time)) return NAN;
  // Half a per-mille of slack at the ends: t-bar = 4 on a run to 4 R0/c0 lands on the last
  // sample up to rounding.
  const double slack = 5e-4 * (t.back() - t.front());
  if (time < t.front() - slack || time > t.back() + slack) return NAN;
  const auto hi = std::lower_bound(t.begin(), t.end(), time);
  if (hi == t.begin()) return a.front();
  if (hi == t.end()) return a.back();
  const std::size_t k = static_cast<std::size_t>(hi - t.begin());
  const double w = (time - t[k - 1]) / (t[k] - t[k - 1]);
  return a[k - 1] + w * (a[k] - a[k - 1]);
}

}  // namespace softshock::server
