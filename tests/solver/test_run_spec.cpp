// The run spec: JSON mapping, defaults (the thesis baseline) and validation errors that name
// the field and the rule.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "softshock/v1/spec.pb.h"
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

// Every example spec in examples/ is valid as shipped; the damage example is the baseline with
// damage on a mesh where l = 5 um spans >= 5 elements (docs/verification.md, "Phase-field damage").
TEST(RunSpec, TheExampleSpecsAreValid) {
  for (const char* name :
       {"baseline", "baseline_damage", "thesis_p1", "richtmyer_meshkov", "richtmyer_meshkov_3d"}) {
    SCOPED_TRACE(name);
    const std::string path = std::string(SOFTSHOCK_SOURCE_DIR) + "/examples/" + name + ".json";
    EXPECT_NO_THROW(normalize_spec(read_spec_file(path)));
  }
  v1::RunSpec damage =
      read_spec_file(std::string(SOFTSHOCK_SOURCE_DIR) + "/examples/baseline_damage.json");
  const v1::RunSpec baseline =
      read_spec_file(std::string(SOFTSHOCK_SOURCE_DIR) + "/examples/baseline.json");
  EXPECT_EQ(damage.damage().model(), v1::TALAMINI);
  EXPECT_EQ(damage.geometry().target_elements(), 66000);
  damage.clear_damage();
  damage.mutable_geometry()->set_target_elements(baseline.geometry().target_elements());
  EXPECT_EQ(spec_to_json(damage), spec_to_json(baseline));
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

// The model's structs and the spec share their defaults (run_spec.cpp reads them from model.hpp):
// a Problem built in code has the spec's physics unless told otherwise.
TEST(RunSpec, TheSpecsDefaultsAreTheModelsDefaults) {
  const auto s = normalize_spec(parse_spec_json("{}"));
  const Problem p = make_problem(normalize_spec(
      parse_spec_json(R"({"geometry":{"target_elements":300},"run":{"end_time":1e-9}})")));
  EXPECT_DOUBLE_EQ(s.material().shear_viscosity(), Material{}.shear_viscosity_Pa_s);
  EXPECT_DOUBLE_EQ(Material{}.shear_viscosity_Pa_s, 0.25);
  EXPECT_DOUBLE_EQ(p.material.shear_viscosity_Pa_s, Material{}.shear_viscosity_Pa_s);
  EXPECT_DOUBLE_EQ(s.material().density(), Material{}.density_kg_m3);
  EXPECT_DOUBLE_EQ(s.viscosity().ramp(), ArtificialViscosity{}.ramp);
  EXPECT_DOUBLE_EQ(s.load().pressure(), PressurePulse{}.pressure_Pa);
  EXPECT_DOUBLE_EQ(s.element().stabilization(), Element{}.stabilization);
  EXPECT_DOUBLE_EQ(s.run().cfl(), SolverOptions{}.cfl);
}

// 3-D geometries: defaults, the problem they set up, and errors naming the field.
TEST(RunSpec, ThreeDimensionalGeometries) {
  const auto c = normalize_spec(parse_spec_json(R"({"geometry":{"cylinder":{}}})"));
  EXPECT_DOUBLE_EQ(c.geometry().cylinder().radius(), 90e-6);
  EXPECT_DOUBLE_EQ(c.geometry().cylinder().thickness(), 50e-6);
  EXPECT_EQ(c.geometry().cylinder().faces(), v1::SLIDING);
  EXPECT_EQ(c.geometry().mesher(), v1::CONCENTRIC_RINGS);
  EXPECT_DOUBLE_EQ(c.geometry().rim_roughness().amplitude(), 3e-4);
  const auto b = normalize_spec(parse_spec_json(R"({"geometry":{"corrugated_box":{}}})"));
  EXPECT_DOUBLE_EQ(b.geometry().corrugated_box().lz(), 40e-6);
  EXPECT_DOUBLE_EQ(b.geometry().corrugated_box().amplitude(), 50e-9);
  EXPECT_EQ(b.geometry().mesher(), v1::FRONTAL_DELAUNAY);
  EXPECT_DOUBLE_EQ(b.geometry().rim_roughness().amplitude(), 0.0);

  EXPECT_EQ(error_field(R"({"geometry":{"cylinder":{"radius":0}}})"), "geometry.cylinder.radius");
  EXPECT_EQ(error_field(R"({"geometry":{"cylinder":{"thickness":-1e-6}}})"),
            "geometry.cylinder.thickness");
  EXPECT_EQ(error_field(R"({"geometry":{"cylinder":{"thickness":1}}})"),
            "geometry.cylinder.thickness");
  EXPECT_EQ(error_field(R"({"geometry":{"cylinder":{"faces":7}}})"), "geometry.cylinder.faces");
  EXPECT_EQ(error_field(R"({"geometry":{"corrugated_box":{"lz":0}}})"),
            "geometry.corrugated_box.lz");
  EXPECT_EQ(error_field(R"({"geometry":{"corrugated_box":{"amplitude":30e-6}}})"),
            "geometry.corrugated_box.amplitude");
  EXPECT_EQ(error_field(R"({"geometry":{"corrugated_box":{"kx":1e5}}})"),
            "geometry.corrugated_box.kx");  // kx lx = 2 is not a multiple of pi
  EXPECT_EQ(error_field(R"({"geometry":{"corrugated_box":{"ky":-314159.26535897932}}})"),
            "geometry.corrugated_box.ky");
  EXPECT_EQ(error_field(R"({"geometry":{"corrugated_box":{},"mesher":"CONCENTRIC_RINGS"}})"),
            "geometry.mesher");
  EXPECT_EQ(error_field(R"({"geometry":{"corrugated_box":{},
      "rim_roughness":{"amplitude":1e-3}}})"),
            "geometry.rim_roughness.amplitude");
  EXPECT_EQ(error_field(R"({"geometry":{"corrugated_box":{"kx":0,"ky":0}}})"), "(accepted)");

  // The cylinder's problem: the pulse on the lateral faces only, the faces held as asked.
  for (const auto* faces : {"SLIDING", "BONDED", "FREE"}) {
    const Problem p = make_problem(normalize_spec(
        parse_spec_json(std::string(R"({"geometry":{"cylinder":{"thickness":20e-6,"faces":")") +
                        faces + R"("},"target_elements":2000,"rim_roughness":{"amplitude":0}}})")));
    ASSERT_EQ(p.mesh.dimension(), 3);
    ASSERT_FALSE(p.loaded_faces.empty());
    EXPECT_FALSE(p.load_all_boundary);
    for (const auto& f : p.loaded_faces)
      for (int32_t i : f) EXPECT_NEAR(std::hypot(p.mesh.x[i], p.mesh.y[i]), 90e-6, 1e-12);
    std::size_t on_faces = 0, fixed_z = 0, fixed_xy = 0;
    for (std::size_t i = 0; i < p.mesh.node_count(); ++i) {
      const bool face = std::fabs(std::fabs(p.mesh.z[i]) - 10e-6) < 1e-15;
      on_faces += face;
      if (!p.fixed_z.empty()) fixed_z += p.fixed_z[i];
      if (!p.fixed_x.empty()) fixed_xy += p.fixed_x[i] && p.fixed_y[i];
    }
    ASSERT_GT(on_faces, 0u);
    EXPECT_EQ(fixed_z, std::string(faces) == "FREE" ? 0u : on_faces) << faces;
    EXPECT_EQ(fixed_xy, std::string(faces) == "BONDED" ? on_faces : 0u) << faces;
    EXPECT_DOUBLE_EQ(p.reference_radius_m, 90e-6);
  }
}

// The README's JSON blocks are specs a reader will copy: each parses with the client's strict
// parser and validates, and the first -- "every default, written out" -- is the defaults.
TEST(RunSpec, TheReadmesSpecsParseAndTheDefaultsBlockIsTheDefaults) {
  std::ifstream in(std::string(SOFTSHOCK_SOURCE_DIR) + "/README.md");
  ASSERT_TRUE(in) << "README.md not found under " << SOFTSHOCK_SOURCE_DIR;
  std::vector<std::string> blocks;
  std::string line, block;
  bool inside = false;
  while (std::getline(in, line)) {
    if (!inside && line.rfind("```json", 0) == 0) {
      inside = true, block.clear();
    } else if (inside && line.rfind("```", 0) == 0) {
      inside = false, blocks.push_back(block);
    } else if (inside) {
      block += line + "\n";
    }
  }
  ASSERT_GE(blocks.size(), 2u) << "the defaults block and the 3-D example";
  for (const auto& json : blocks) {
    SCOPED_TRACE(json);
    v1::RunSpec spec;
    ASSERT_NO_THROW(spec = parse_spec_json(json));
    EXPECT_NO_THROW(validate_spec(with_defaults(spec)));
  }
  EXPECT_EQ(spec_to_json(normalize_spec(parse_spec_json(blocks.front()))),
            spec_to_json(normalize_spec(parse_spec_json("{}"))));
}

TEST(RunSpec, MalformedJsonAndUnknownFieldsAreRejected) {
  EXPECT_EQ(error_field(R"({"geometry":{"disk":{"radius":1e-4}},"colour":"red"})"), "spec");
  EXPECT_EQ(error_field(R"({"geometry":)"), "spec");
  EXPECT_EQ(error_field(R"({"load":{"shape":"TRIANGLE"}})"), "spec");
  EXPECT_THROW(read_spec_file("/nonexistent/spec.json"), SpecError);
  // A spec a daemon stored is read leniently: a field from a newer release is ignored.
  EXPECT_DOUBLE_EQ(
      parse_spec_json(R"({"run":{"cfl":0.5},"colour":"red"})", SpecJson::kStored).run().cfl(), 0.5);
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
