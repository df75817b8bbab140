// The run spec: JSON mapping, defaults (the thesis baseline) and validation errors that name
// the field and the rule.
#include <gtest/gtest.h>

#include "solver/model.hpp"
#include "solver/run_spec.hpp"

namespace softshock {
namespace {

TEST(RunSpec, JsonMappingUsesDocumentedFieldNames) {
  const auto spec = parse_spec_json(R"({"geometry":{"disk":{"radius":9e-5},"target_elements":1000},
    "load":{"pressure":1e9,"duration":4e-9,"shape":"GAUSSIAN"},"run":{"end_time":1e-7}})");
  EXPECT_DOUBLE_EQ(spec.geometry().disk().radius(), 9e-5);
  EXPECT_EQ(spec.geometry().target_elements(), 1000);
  EXPECT_EQ(spec.load().shape(), v1::GAUSSIAN);
  EXPECT_FALSE(spec.material().has_density());
}

TEST(RunSpec, DefaultsAreTheThesisBaseline) {
  const auto s = normalize_spec(parse_spec_json("{}"));
  EXPECT_DOUBLE_EQ(s.geometry().disk().radius(), 90e-6);
  EXPECT_EQ(s.geometry().target_elements(), 16500);
  EXPECT_DOUBLE_EQ(s.material().density(), 1000);
  EXPECT_DOUBLE_EQ(s.material().bulk_modulus(), 2e9);
  EXPECT_DOUBLE_EQ(s.material().shear_modulus(), 5e3);
  EXPECT_DOUBLE_EQ(s.material().tait_gamma(), 6.15);
  EXPECT_DOUBLE_EQ(s.viscosity().c1(), 1.0);
  EXPECT_DOUBLE_EQ(s.viscosity().c2(), 0.1);
  EXPECT_DOUBLE_EQ(s.load().pressure(), 2e9);
  EXPECT_DOUBLE_EQ(s.load().duration(), 8e-9);
  EXPECT_EQ(s.load().shape(), v1::SQUARE);
  EXPECT_DOUBLE_EQ(s.run().end_time(), 800e-9);
  EXPECT_DOUBLE_EQ(s.run().cfl(), 0.75);  // the thesis ran 0.5 (examples/thesis_p1.json)
  EXPECT_DOUBLE_EQ(s.run().history_interval(), 1e-9);
  EXPECT_EQ(s.run().modes(), 64);
  EXPECT_EQ(s.run().threads(), 1);
  EXPECT_DOUBLE_EQ(s.run().max_aspect_ratio(), 100);  // not the thesis's: it had no such stop
  EXPECT_DOUBLE_EQ(make_options(s).max_aspect_ratio, 100);
  EXPECT_EQ(s.element().mass_blend(), 1.0);  // one step towards the consistent mass
  EXPECT_EQ(make_problem(normalize_spec(parse_spec_json(R"({"geometry":{"target_elements":300},
      "element":{"mass_blend":0}})")))
                .element.mass_blend,
            0.0);  // lumped, as the thesis ran, on request
  // Explicit values survive; the canonical JSON has every field and parses back equal.
  const auto back = parse_spec_json(spec_to_json(s));
  EXPECT_EQ(back.SerializeAsString(), s.SerializeAsString());
  EXPECT_NE(spec_to_json(s).find("\"bulk_modulus\""), std::string::npos);
}

std::string error_field(const std::string& json, const SpecLimits& limits = {}) {
  try {
    normalize_spec(parse_spec_json(json), limits);
  } catch (const SpecError& e) {
    EXPECT_NE(std::string(e.what()).find(e.field()), std::string::npos);
    return e.field();
  }
  return "(accepted)";
}

TEST(RunSpec, InvalidFieldsAreNamed) {
  EXPECT_EQ(error_field(R"({"geometry":{"disk":{"radius":-1e-5}}})"), "geometry.disk.radius");
  EXPECT_EQ(error_field(R"({"material":{"shear_modulus":-1}})"), "material.shear_modulus");
  EXPECT_EQ(error_field(R"({"material":{"density":0}})"), "material.density");
  EXPECT_EQ(error_field(R"({"material":{"bulk_modulus":"NaN"}})"), "material.bulk_modulus");
  EXPECT_EQ(error_field(R"({"run":{"cfl":1.0}})"), "run.cfl");
  EXPECT_EQ(error_field(R"({"run":{"cfl":0}})"), "run.cfl");
  EXPECT_EQ(error_field(R"({"run":{"end_time":-1}})"), "run.end_time");
  EXPECT_EQ(error_field(R"({"run":{"threads":0}})"), "run.threads");
  EXPECT_EQ(error_field(R"({"run":{"modes":-2}})"), "run.modes");
  EXPECT_EQ(error_field(R"({"run":{"max_aspect_ratio":-1}})"), "run.max_aspect_ratio");
  EXPECT_EQ(error_field(R"({"run":{"max_aspect_ratio":1.15}})"), "run.max_aspect_ratio");
  EXPECT_EQ(error_field(R"({"run":{"max_aspect_ratio":"Infinity"}})"), "run.max_aspect_ratio");
  EXPECT_EQ(error_field(R"({"element":{"mass_blend":-0.1}})"), "element.mass_blend");
  EXPECT_EQ(error_field(R"({"element":{"mass_blend":1.5}})"), "element.mass_blend");
  EXPECT_EQ(error_field(R"({"element":{"mass_blend":"NaN"}})"), "element.mass_blend");
  EXPECT_EQ(error_field(R"({"run":{"max_aspect_ratio":0}})"), "(accepted)");  // no limit
  EXPECT_EQ(error_field(R"({"run":{"max_aspect_ratio":1.16}})"), "(accepted)");
  EXPECT_EQ(error_field(R"({"load":{"duration":0}})"), "load.duration");
  EXPECT_EQ(error_field(R"({"viscosity":{"c1":-0.5}})"), "viscosity.c1");
  EXPECT_EQ(error_field(R"({"geometry":{"rounded_square":{"side":1e-4,"corner_radius":6e-5}}})"),
            "geometry.rounded_square.corner_radius");
  EXPECT_EQ(error_field(R"({"geometry":{"mesh_file":"/nonexistent/disk.msh"}})"),
            "geometry.mesh_file");
  SpecLimits limits;
  limits.max_elements = 10000;
  EXPECT_EQ(error_field(R"({"geometry":{"target_elements":20000}})", limits),
            "geometry.target_elements");
  EXPECT_EQ(error_field(R"({"run":{"end_time":1e-3}})"), "run.end_time");
  EXPECT_EQ(error_field(R"({"run":{"end_time":1e-6,"history_interval":1e-15}})"),
            "run.history_interval");
  EXPECT_EQ(error_field("{}"), "(accepted)");
}

TEST(RunSpec, MalformedJsonAndUnknownFieldsAreRejected) {
  EXPECT_EQ(error_field(R"({"geometry":{"disk":{"radius":1e-4}},"colour":"red"})"), "spec");
  EXPECT_EQ(error_field(R"({"geometry":)"), "spec");
  EXPECT_EQ(error_field(R"({"load":{"shape":"TRIANGLE"}})"), "spec");
  EXPECT_THROW(read_spec_file("/nonexistent/spec.json"), SpecError);
}

TEST(PressurePulse, ShapesDeliverTheirDocumentedImpulse) {
  for (auto shape :
       {PulseShape::kSquare, PulseShape::kGaussian, PulseShape::kLinear, PulseShape::kQuadratic}) {
    const PressurePulse pulse{shape, 2e9, 8e-9};
    const int n = 200000;
    const double dt = 1.1 * pulse.end_s() / n;
    double impulse = 0;
    for (int k = 0; k < n; ++k) impulse += pulse.at((k + 0.5) * dt) * dt;
    // Midpoint rule: error ~ one step's worth at the square pulse's jump, 1/n relative.
    EXPECT_NEAR(impulse, pulse.impulse_Pa_s(), 2e-5 * pulse.impulse_Pa_s());
    EXPECT_EQ(pulse.at(pulse.end_s() * 1.0001), 0.0);
    EXPECT_EQ(pulse.at(-1e-12), 0.0);
  }
  EXPECT_DOUBLE_EQ((PressurePulse{PulseShape::kLinear, 1.0, 2.0}.at(1.0)), 1.0);
  EXPECT_DOUBLE_EQ((PressurePulse{PulseShape::kQuadratic, 1.0, 2.0}.at(1.0)), 1.0);
  EXPECT_DOUBLE_EQ((PressurePulse{PulseShape::kGaussian, 1.0, 2.0}.at(3.0)), 1.0);
}

}  // namespace
}  // namespace softshock
