// Grid expansion: axis values, the mapping of nondimensional groups onto spec fields,
// canonical specs (identical runs hash equal), validation errors naming the field, and the
// per-point reduction (A-bar at a given t-bar).
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "server/jobs/grid.hpp"

namespace softshock::server {
namespace {

v1::GridAxis list_axis(const std::string& name, std::vector<double> values) {
  v1::GridAxis a;
  a.set_name(name);
  a.mutable_values()->Assign(values.begin(), values.end());
  return a;
}

v1::GridAxis span_axis(const std::string& name, double start, double stop, int num,
                       bool geometric = false) {
  v1::GridAxis a;
  a.set_name(name);
  v1::Span* s = geometric ? a.mutable_geomspace() : a.mutable_linspace();
  s->set_start(start);
  s->set_stop(stop);
  s->set_num(num);
  return a;
}

google::protobuf::RepeatedPtrField<v1::GridAxis> axes(std::vector<v1::GridAxis> list) {
  google::protobuf::RepeatedPtrField<v1::GridAxis> out;
  for (auto& a : list) *out.Add() = std::move(a);
  return out;
}

v1::RunSpec small_base() {
  v1::RunSpec s;
  s.mutable_geometry()->mutable_disk()->set_radius(90e-6);
  s.mutable_geometry()->set_target_elements(300);
  s.mutable_run()->set_end_time(2e-8);
  return s;
}

// The field named in a SpecError thrown by f.
template <typename F>
std::string error_field(F&& f) {
  try {
    f();
  } catch (const SpecError& e) {
    return e.field();
  }
  return "(no error)";
}

TEST(GridAxis, ListLinspaceGeomspace) {
  EXPECT_EQ(axis_values(list_axis("pbar", {1, 0.5}), "a"), (std::vector<double>{1, 0.5}));
  const auto lin = axis_values(span_axis("pbar", 0.5, 1.5, 11), "a");
  ASSERT_EQ(lin.size(), 11u);
  EXPECT_DOUBLE_EQ(lin.front(), 0.5);
  EXPECT_DOUBLE_EQ(lin[5], 1.0);
  EXPECT_EQ(lin.back(), 1.5);
  EXPECT_EQ(lin[2], 0.7) << "values are canonical (12 significant digits), not 0.7000000000000001";
  const auto geo = axis_values(span_axis("mubar", 1e-6, 1e-4, 3, true), "a");
  ASSERT_EQ(geo.size(), 3u);
  EXPECT_DOUBLE_EQ(geo[1], 1e-5);
  EXPECT_EQ(axis_values(span_axis("gamma", 6, 7, 1), "a"), (std::vector<double>{6}));

  EXPECT_EQ(error_field([] { axis_values(v1::GridAxis{}, "axes[0]"); }), "axes[0]");
  EXPECT_EQ(error_field([] { axis_values(span_axis("pbar", 0.5, 1.5, 0), "axes[1]"); }),
            "axes[1].linspace.num");
  EXPECT_EQ(error_field([] { axis_values(span_axis("pbar", 0, 1, 3, true), "axes[0]"); }),
            "axes[0].geomspace");
  EXPECT_EQ(error_field([] {
              axis_values(list_axis("pbar", {1, 1.0}), "axes[0]");
            }),
            "axes[0].values");
  EXPECT_EQ(error_field([] { axis_values(list_axis("pbar", {NAN}), "axes[0]"); }),
            "axes[0].values");
  EXPECT_EQ(error_field([] { axis_values(span_axis("pbar", 0.5, 1.5, 1001), "axes[0]"); }),
            "axes[0].linspace.num");
}

TEST(GridAxis, GroupsMapOntoDimensionalFields) {
  v1::RunSpec s = with_defaults(small_base());  // kappa 2e9, rho0 1000, R0 90 um
  apply_grid_value(s, "pbar", 0.75);
  EXPECT_DOUBLE_EQ(s.load().pressure(), 1.5e9);
  apply_grid_value(s, "mubar", 5e-6);
  EXPECT_DOUBLE_EQ(s.material().shear_modulus(), 1e4);
  apply_grid_value(s, "tbar_pulse", 0.2);
  const double time_scale = 90e-6 / std::sqrt(2e9 / 1000.0);  // 63.64 ns
  EXPECT_NEAR(s.load().duration(), 0.2 * time_scale, 1e-20);
  apply_grid_value(s, "Gamma", 7);  // group names in any case
  EXPECT_DOUBLE_EQ(s.material().tait_gamma(), 7);
  apply_grid_value(s, "c1", 2);
  apply_grid_value(s, "c2", 0.3);
  EXPECT_DOUBLE_EQ(s.viscosity().c1(), 2);
  EXPECT_DOUBLE_EQ(s.viscosity().c2(), 0.3);
  const NondimensionalGroups g = spec_groups(s);
  EXPECT_DOUBLE_EQ(g.pbar, 0.75);
  EXPECT_NEAR(g.tbar_pulse, 0.2, 1e-12);
  EXPECT_DOUBLE_EQ(g.mubar, 5e-6);

  // Spec fields by proto or JSON name; integer fields take integers only.
  apply_grid_value(s, "load.pressure", 3e9);
  EXPECT_DOUBLE_EQ(s.load().pressure(), 3e9);
  apply_grid_value(s, "geometry.targetElements", 500);
  EXPECT_EQ(s.geometry().target_elements(), 500);
  EXPECT_EQ(error_field([&] { apply_grid_value(s, "geometry.target_elements", 2.5, "axes[0]"); }),
            "axes[0].values");
  EXPECT_EQ(error_field([&] { apply_grid_value(s, "load.shape", 1, "axes[0]"); }), "axes[0].name");
  EXPECT_EQ(error_field([&] { apply_grid_value(s, "load.nope", 1, "axes[2]"); }), "axes[2].name");
  EXPECT_EQ(error_field([&] { apply_grid_value(s, "geometry.rounded_square.side", 1e-4, "ax"); }),
            "ax.name")
      << "the base is a disk";
  v1::RunSpec mesh = s;
  mesh.mutable_geometry()->set_mesh_file("m.msh");
  EXPECT_EQ(error_field([&] { apply_grid_value(mesh, "tbar_pulse", 0.1, "ax"); }), "ax.name")
      << "a mesh file's R0 is unknown before meshing";
}

TEST(GridExpansion, RowMajorPointsAndValidation) {
  const auto plan = expand_grid(
      small_base(),
      axes({list_axis("pbar", {0.5, 1.0, 1.5}), span_axis("tbar_pulse", 0.1, 0.2, 2)}), {});
  EXPECT_EQ(plan.shape, (std::vector<int>{3, 2}));
  ASSERT_EQ(plan.points.size(), 6u);
  // Last axis fastest: point 3 is (pbar 1.0, tbar_pulse 0.2).
  const NondimensionalGroups g3 = spec_groups(plan.points[3].spec);
  EXPECT_DOUBLE_EQ(g3.pbar, 1.0);
  EXPECT_NEAR(g3.tbar_pulse, 0.2, 1e-9);
  EXPECT_EQ(plan.axes[1].values_size(), 2);
  std::set<std::string> hashes;
  for (const auto& p : plan.points) hashes.insert(p.hash);
  EXPECT_EQ(hashes.size(), 6u);

  // A group axis uses the point's own kappa: P-bar stays what the axis says.
  const auto kappa =
      expand_grid(small_base(),
                  axes({list_axis("pbar", {1.0}), list_axis("material.bulk_modulus", {4e9})}), {});
  EXPECT_DOUBLE_EQ(kappa.points[0].spec.load().pressure(), 4e9);

  EXPECT_EQ(error_field([] { expand_grid(small_base(), axes({}), {}); }), "axes");
  EXPECT_EQ(error_field([] {
              expand_grid(small_base(),
                          axes({list_axis("pbar", {1}), list_axis("c1", {1}), list_axis("c2", {1}),
                                list_axis("gamma", {6})}),
                          {});
            }),
            "axes");
  EXPECT_EQ(error_field([] {
              expand_grid(small_base(),
                          axes({list_axis("pbar", {1}), list_axis("load.pressure", {1e9})}), {});
            }),
            "axes[1].name")
      << "two axes setting load.pressure";
  EXPECT_EQ(error_field([] {
              expand_grid(small_base(),
                          axes({span_axis("pbar", 0.1, 2, 101), span_axis("gamma", 5, 7, 100)}),
                          {});
            }),
            "axes")
      << "more than 10,000 points";
  EXPECT_EQ(error_field([] {
              expand_grid(small_base(), axes({list_axis("pbar", {1, 300})}), {});
            }),
            "axes")
      << "a point breaking a spec rule (pressure > 100 kappa)";
  EXPECT_EQ(error_field([] { expand_grid(small_base(), axes({list_axis("", {1})}), {}); }),
            "axes[0].name");
}

TEST(CanonicalSpec, IdenticalRunsHashEqual) {
  SpecLimits limits;
  v1::RunSpec a = small_base();
  a.mutable_viscosity()->set_c1(1);
  v1::RunSpec b = small_base();
  b.mutable_viscosity()->set_c1(1.0);
  b.mutable_material()->set_tait_gamma(6.15);  // the default, written out
  EXPECT_EQ(canonical_spec(a, limits).hash, canonical_spec(b, limits).hash);

  // Computed two ways: 0.7 x 2e9 vs 1.4e9 differ in the last bit, not after canonicalising.
  v1::RunSpec c = small_base();
  c.mutable_load()->set_pressure(0.7 * 2e9 * (1 + 1e-15));
  v1::RunSpec d = small_base();
  d.mutable_load()->set_pressure(1.4e9);
  EXPECT_NE(c.load().pressure(), d.load().pressure());
  EXPECT_EQ(canonical_spec(c, limits).hash, canonical_spec(d, limits).hash);

  v1::RunSpec e = small_base();
  e.mutable_load()->set_pressure(1.41e9);
  EXPECT_NE(canonical_spec(e, limits).hash, canonical_spec(d, limits).hash);

  // A grid point and the same run submitted by hand hash equal.
  const auto plan = expand_grid(small_base(), axes({list_axis("pbar", {0.7})}), limits);
  EXPECT_EQ(plan.points[0].hash, canonical_spec(d, limits).hash);
}

TEST(GridReduction, QuantitiesFromTheStoredSummary) {
  StoredSummary s;
  s.summary.max_abar_first_cycle = 0.02;
  s.summary.energy_injected_J_per_m = 5;
  s.summary.shock_at_center_s = -1;
  s.summary.groups.time_scale_s = 10e-9;
  s.abar_times = {0, 10e-9, 20e-9, 40e-9};
  s.abar_values = {0, 0.01, 0.03, 0.05};
  auto q = [&](const char* name, double tbar = 0) {
    return grid_quantity(*find_grid_quantity(name), s, tbar);
  };
  EXPECT_DOUBLE_EQ(q("max_abar_first_cycle"), 0.02);
  EXPECT_DOUBLE_EQ(q("energy_injected_J_per_m"), 5);
  EXPECT_TRUE(std::isnan(q("shock_at_center_s"))) << "not detected";
  // The names before the summary's carried units still find the same quantities.
  EXPECT_DOUBLE_EQ(q("energy_injected"), 5);
  EXPECT_STREQ(find_grid_quantity("energy_injected")->name, "energy_injected_J_per_m");
  EXPECT_STREQ(find_grid_quantity("wall_time")->name, "wall_time_s");
  EXPECT_TRUE(std::isnan(q("shock_at_center"))) << "not detected";
  EXPECT_DOUBLE_EQ(q("abar_at", 1.0), 0.01);
  EXPECT_DOUBLE_EQ(q("abar_at", 1.5), 0.02);
  EXPECT_DOUBLE_EQ(q("abar_at", 3.0), 0.04);
  EXPECT_DOUBLE_EQ(q("abar_at", 4.0), 0.05);
  EXPECT_TRUE(std::isnan(q("abar_at", 5.0))) << "after the end of the run";
  EXPECT_EQ(find_grid_quantity("nope"), nullptr);
  // Damage figures: NaN for a run without damage, and the onset of one never damaged.
  EXPECT_TRUE(std::isnan(q("damage_onset_s")));
  EXPECT_TRUE(std::isnan(q("max_damaged_radius_m")));
  s.summary.damage = true;
  s.summary.max_damaged_radius_m = 3e-6;
  EXPECT_TRUE(std::isnan(q("damage_onset_s"))) << "damaged nowhere (onset -1)";
  s.summary.damage_onset_s = 1.2e-8;
  EXPECT_DOUBLE_EQ(q("damage_onset_s"), 1.2e-8);
  EXPECT_DOUBLE_EQ(q("max_damaged_radius_m"), 3e-6);
  EXPECT_STREQ(grid_quantities().front().name, "max_abar_first_cycle");
}

}  // namespace
}  // namespace softshock::server
