#include "run_spec.hpp"

#include <google/protobuf/util/json_util.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

#include "gmsh_mesher.hpp"
#include "mesh_file_path.hpp"
#include "rim_roughness.hpp"
#include "ring_mesher.hpp"

namespace softshock {
namespace {

namespace pb = google::protobuf;

// The thesis baseline (docs/model.md).
constexpr double kRadius = 90e-6, kSide = 540e-6, kCornerRadius = 90e-6;
constexpr int kTargetElements = 16500;
// The model's own defaults (model.hpp), so that a Problem built in code and a spec agree.
constexpr double kDensity = Material{}.density_kg_m3, kKappa = Material{}.bulk_modulus_Pa,
                 kMu = Material{}.shear_modulus_Pa, kGamma = Material{}.tait_gamma,
                 kShearViscosity = Material{}.shear_viscosity_Pa_s;
constexpr double kC1 = ArtificialViscosity{}.c1, kC2 = ArtificialViscosity{}.c2,
                 kRamp = ArtificialViscosity{}.ramp;
constexpr double kElementWeight = Element{}.element_weight,
                 kStabilization = Element{}.stabilization, kMassBlend = Element{}.mass_blend;
constexpr double kDamageLength = Damage{}.length_m, kEpsilonF = Damage{}.epsilon_f_Pa,
                 kFractureEnergy = Damage{}.fracture_energy_J_m2, kZeta = Damage{}.zeta_Pa_s;
constexpr int kDamageUpdateEvery = Damage{}.update_every;
constexpr double kRoughness = 3e-4;
constexpr int kRoughnessMinMode = 2, kRoughnessMaxMode = 16;
constexpr double kStripWavelength = 10e-6, kStripHeight = 40e-6, kStripAmplitude = 50e-9;
constexpr double kCylinderThickness = 50e-6;  // the experiments' gel layer
constexpr double kBoxLx = 20e-6, kBoxLy = 20e-6, kBoxLz = 40e-6, kBoxAmplitude = 50e-9;
constexpr double kBoxKx = 2.0 * std::numbers::pi / 10e-6, kBoxKy = 2.0 * std::numbers::pi / 20e-6;
constexpr double kPressure = PressurePulse{}.pressure_Pa, kDuration = PressurePulse{}.duration_s;
// The run's defaults are the solver's own (model.hpp), as the element's are.
constexpr double kEndTime = SolverOptions{}.end_time_s, kCfl = SolverOptions{}.cfl,
                 kOutputInterval = SolverOptions{}.output_interval_s,
                 kHistoryInterval = SolverOptions{}.history_interval_s;
constexpr int kModes = SolverOptions{}.modes, kThreads = SolverOptions{}.threads;
// The default runs (P-bar <= 1.5) stay below ~70; at 100 the mesh no longer follows the flow
// (docs/verification.md, "stronger pulses").
constexpr double kMaxAspectRatio = 100;
constexpr double kEquilateralAspectRatio = 1.1547005383792515;  // 2 / sqrt(3), the smallest
constexpr int kMinElements = 20;

void require(bool ok, const char* field, const std::string& rule) {
  if (!ok) throw SpecError(field, rule);
}

void require_finite_positive(double v, const char* field) {
  require(std::isfinite(v) && v > 0, field, "must be a finite number > 0");
}

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// Material, viscosity and load of a normalized spec.
void set_parameters(const v1::RunSpec& s, Problem& p) {
  const auto& m = s.material();
  p.material = {m.density(), m.bulk_modulus(), m.shear_modulus(), m.tait_gamma(),
                m.shear_viscosity()};
  const auto& v = s.viscosity();
  p.viscosity = {v.c1(), v.c2(), true,
                 v.activation() == v1::COMPRESSION_ONLY ? ViscositySwitch::kCompressionOnly
                                                        : ViscositySwitch::kContinuous,
                 v.ramp()};
  p.element = {s.element().formulation() == v1::P1 ? ElementFormulation::kP1
                                                   : ElementFormulation::kAverageNodalPressure,
               s.element().element_weight(), s.element().stabilization(), s.element().mass_blend()};
  const auto& l = s.load();
  PulseShape shape = PulseShape::kSquare;
  if (l.shape() == v1::GAUSSIAN) shape = PulseShape::kGaussian;
  if (l.shape() == v1::LINEAR) shape = PulseShape::kLinear;
  if (l.shape() == v1::QUADRATIC) shape = PulseShape::kQuadratic;
  p.load = {shape, l.pressure(), l.duration()};
  p.perturbation = {l.perturbation().mode(), l.perturbation().amplitude()};
  if (s.has_damage()) {
    const auto& d = s.damage();
    p.damage.model = d.model() == v1::TALAMINI     ? DamageModel::kTalamini
                     : d.model() == v1::GIOVANARDI ? DamageModel::kGiovanardi
                                                   : DamageModel::kNone;
    p.damage.length_m = d.length();
    p.damage.epsilon_f_Pa = d.epsilon_f();
    p.damage.fracture_energy_J_m2 = d.fracture_energy();
    p.damage.zeta_Pa_s = d.zeta();
    p.damage.update_every = d.update_every();
    p.damage.linear_solver = d.linear_solver() == v1::DIRECT      ? DamageLinearSolver::kDirect
                             : d.linear_solver() == v1::ITERATIVE ? DamageLinearSolver::kIterative
                                                                  : DamageLinearSolver::kAuto;
  }
}

// The planar Richtmyer-Meshkov target: sliding walls at both sides, the pulse on the bottom,
// the corrugated top free. The diagnostics' polar frame is centred on the bottom's middle with
// R0 = height, so "rim" figures describe the whole outline; read the top surface from frames.
void set_up_corrugated_strip(const v1::Geometry& g, Problem& p) {
  const auto& c = g.corrugated_strip();
  const double width = 0.5 * c.wavelength(), tol = 1e-9 * width;
  const std::size_t nn = p.mesh.node_count();
  p.fixed_x.assign(nn, 0);
  for (std::size_t i = 0; i < nn; ++i)
    if (p.mesh.x[i] < tol || p.mesh.x[i] > width - tol) p.fixed_x[i] = 1;
  p.load_all_boundary = false;
  for (const auto& e : p.mesh.boundary_edges)
    if (p.mesh.y[e[0]] < tol && p.mesh.y[e[1]] < tol) p.loaded_edges.push_back(e);
  p.origin = {0.5 * width, 0.0};
  p.reference_radius_m = c.height();
}

// The nodes of a 3-D mesh with |coordinate - value| <= tol.
std::vector<uint8_t> nodes_at(const std::vector<double>& coordinate, double value, double tol) {
  std::vector<uint8_t> out(coordinate.size(), 0);
  for (std::size_t i = 0; i < coordinate.size(); ++i)
    out[i] = std::fabs(coordinate[i] - value) <= tol ? 1 : 0;
  return out;
}

// The cylinder: the pulse on the lateral surface (the boundary faces not on a face), the faces
// held as asked; the rim diagnostics at the mid-plane z = 0.
void set_up_cylinder(const v1::Geometry& g, Problem& p) {
  const auto& c = g.cylinder();
  const double half = 0.5 * c.thickness(), tol = 1e-9 * c.radius();
  const std::vector<uint8_t> top = nodes_at(p.mesh.z, half, tol),
                             bottom = nodes_at(p.mesh.z, -half, tol);
  p.load_all_boundary = false;
  for (const auto& f : p.mesh.boundary_faces) {
    const bool on_top = top[f[0]] && top[f[1]] && top[f[2]];
    const bool on_bottom = bottom[f[0]] && bottom[f[1]] && bottom[f[2]];
    if (!on_top && !on_bottom) p.loaded_faces.push_back(f);
  }
  const std::size_t nn = p.mesh.node_count();
  if (c.faces() != v1::FREE) {
    p.fixed_z.assign(nn, 0);
    if (c.faces() == v1::BONDED) p.fixed_x.assign(nn, 0), p.fixed_y.assign(nn, 0);
    for (std::size_t i = 0; i < nn; ++i) {
      if (!top[i] && !bottom[i]) continue;
      p.fixed_z[i] = 1;
      if (c.faces() == v1::BONDED) p.fixed_x[i] = 1, p.fixed_y[i] = 1;
    }
  }
  p.origin = {0.0, 0.0};
  p.reference_radius_m = c.radius();
  p.mid_plane_z_m = 0.0;
}

// The corrugated box: sliding walls on its four sides, the pulse on z = 0, the top free. No rim.
void set_up_corrugated_box(const v1::Geometry& g, Problem& p) {
  const auto& b = g.corrugated_box();
  const double tol = 1e-9 * std::min({b.lx(), b.ly(), b.lz()});
  const std::size_t nn = p.mesh.node_count();
  p.fixed_x.assign(nn, 0), p.fixed_y.assign(nn, 0);
  for (std::size_t i = 0; i < nn; ++i) {
    if (p.mesh.x[i] < tol || p.mesh.x[i] > b.lx() - tol) p.fixed_x[i] = 1;
    if (p.mesh.y[i] < tol || p.mesh.y[i] > b.ly() - tol) p.fixed_y[i] = 1;
  }
  p.load_all_boundary = false;
  for (const auto& f : p.mesh.boundary_faces)
    if (p.mesh.z[f[0]] < tol && p.mesh.z[f[1]] < tol && p.mesh.z[f[2]] < tol)
      p.loaded_faces.push_back(f);
  p.origin = {0.5 * b.lx(), 0.5 * b.ly()};
  p.reference_radius_m = b.lz();
  p.mid_plane_z_m = 0.5 * b.lz();
  p.rim_diagnostics = false;
  p.center_region_radius_m = 0.1 * std::min({b.lx(), b.ly(), b.lz()});
}

// Whether kl is a positive or zero multiple of pi (a symmetry plane of cos(k x) at x = l).
bool multiple_of_pi(double kl) {
  const double m = kl / std::numbers::pi;
  return kl >= 0 && std::fabs(m - std::round(m)) <= 1e-9 * std::max(1.0, m);
}

}  // namespace

v1::RunSpec parse_spec_json(const std::string& json, SpecJson source) {
  v1::RunSpec spec;
  pb::util::JsonParseOptions options;
  options.ignore_unknown_fields = source == SpecJson::kStored;
  const auto status = pb::util::JsonStringToMessage(json, &spec, options);
  if (!status.ok()) {
    throw SpecError("spec",
                    std::string(source == SpecJson::kStored ? "stored spec does not parse: "
                                                            : "invalid JSON for RunSpec: ") +
                        std::string(status.message()));
  }
  return spec;
}

v1::RunSpec read_spec_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw SpecError("spec", "cannot read spec file '" + path + "'");
  std::stringstream buffer;
  buffer << in.rdbuf();
  try {
    return parse_spec_json(buffer.str());
  } catch (const SpecError& e) {
    throw SpecError("spec", path + ": " + std::string(e.what()).substr(6));
  }
}

v1::RunSpec with_defaults(const v1::RunSpec& in) {
  v1::RunSpec s = in;
  auto* g = s.mutable_geometry();
  switch (g->shape_case()) {
    case v1::Geometry::SHAPE_NOT_SET:
      g->mutable_disk()->set_radius(kRadius);
      break;
    case v1::Geometry::kDisk:
      if (!g->disk().has_radius()) g->mutable_disk()->set_radius(kRadius);
      break;
    case v1::Geometry::kRoundedSquare:
      if (!g->rounded_square().has_side()) g->mutable_rounded_square()->set_side(kSide);
      if (!g->rounded_square().has_corner_radius())
        g->mutable_rounded_square()->set_corner_radius(kCornerRadius);
      break;
    case v1::Geometry::kMeshFile:
      break;
    case v1::Geometry::kCorrugatedStrip: {
      auto* c = g->mutable_corrugated_strip();
      if (!c->has_wavelength()) c->set_wavelength(kStripWavelength);
      if (!c->has_height()) c->set_height(kStripHeight);
      if (!c->has_amplitude()) c->set_amplitude(kStripAmplitude);
      break;
    }
    case v1::Geometry::kCylinder: {
      auto* c = g->mutable_cylinder();
      if (!c->has_radius()) c->set_radius(kRadius);
      if (!c->has_thickness()) c->set_thickness(kCylinderThickness);
      if (c->faces() == v1::FACE_CONDITION_UNSPECIFIED) c->set_faces(v1::SLIDING);
      break;
    }
    case v1::Geometry::kCorrugatedBox: {
      auto* b = g->mutable_corrugated_box();
      if (!b->has_lx()) b->set_lx(kBoxLx);
      if (!b->has_ly()) b->set_ly(kBoxLy);
      if (!b->has_lz()) b->set_lz(kBoxLz);
      if (!b->has_amplitude()) b->set_amplitude(kBoxAmplitude);
      if (!b->has_kx()) b->set_kx(kBoxKx);
      if (!b->has_ky()) b->set_ky(kBoxKy);
      break;
    }
  }
  if (!g->has_target_elements()) g->set_target_elements(kTargetElements);
  if (g->mesher() == v1::MESHER_UNSPECIFIED)
    g->set_mesher(g->has_disk() || g->has_cylinder() ? v1::CONCENTRIC_RINGS : v1::FRONTAL_DELAUNAY);
  if (!g->has_mesh_rotation()) g->set_mesh_rotation(0.0);
  auto* rough = g->mutable_rim_roughness();
  const bool star_shaped = g->has_disk() || g->has_rounded_square() || g->has_cylinder();
  if (!rough->has_amplitude()) rough->set_amplitude(star_shaped ? kRoughness : 0.0);
  if (!rough->has_min_mode()) rough->set_min_mode(kRoughnessMinMode);
  if (!rough->has_max_mode()) rough->set_max_mode(kRoughnessMaxMode);
  if (!rough->has_seed()) rough->set_seed(1);
  auto* m = s.mutable_material();
  if (!m->has_density()) m->set_density(kDensity);
  if (!m->has_bulk_modulus()) m->set_bulk_modulus(kKappa);
  if (!m->has_shear_modulus()) m->set_shear_modulus(kMu);
  if (!m->has_tait_gamma()) m->set_tait_gamma(kGamma);
  if (!m->has_shear_viscosity()) m->set_shear_viscosity(kShearViscosity);
  auto* v = s.mutable_viscosity();
  if (!v->has_c1()) v->set_c1(kC1);
  if (!v->has_c2()) v->set_c2(kC2);
  if (v->activation() == v1::VISCOSITY_ACTIVATION_UNSPECIFIED) v->set_activation(v1::CONTINUOUS);
  if (!v->has_ramp()) v->set_ramp(kRamp);
  auto* el = s.mutable_element();
  if (el->formulation() == v1::ELEMENT_FORMULATION_UNSPECIFIED)
    el->set_formulation(v1::AVERAGE_NODAL_PRESSURE);
  if (!el->has_element_weight()) el->set_element_weight(kElementWeight);
  if (!el->has_stabilization()) el->set_stabilization(kStabilization);
  if (!el->has_mass_blend()) el->set_mass_blend(kMassBlend);
  auto* l = s.mutable_load();
  if (!l->has_pressure()) l->set_pressure(kPressure);
  if (!l->has_duration()) l->set_duration(kDuration);
  if (l->shape() == v1::PULSE_SHAPE_UNSPECIFIED) l->set_shape(v1::SQUARE);
  if (!l->perturbation().has_mode()) l->mutable_perturbation()->set_mode(0);
  if (!l->perturbation().has_amplitude()) l->mutable_perturbation()->set_amplitude(0.0);
  auto* r = s.mutable_run();
  if (!r->has_end_time()) r->set_end_time(kEndTime);
  if (!r->has_cfl()) r->set_cfl(kCfl);
  if (!r->has_output_interval()) r->set_output_interval(kOutputInterval);
  if (!r->has_history_interval()) r->set_history_interval(kHistoryInterval);
  if (!r->has_modes()) r->set_modes(kModes);
  if (!r->has_threads()) r->set_threads(kThreads);
  if (!r->has_max_aspect_ratio()) r->set_max_aspect_ratio(kMaxAspectRatio);
  // Damage: absent unless a model is asked for, so that a spec without damage (or with model NONE)
  // normalises to exactly what it did before damage existed (the same stored spec and hash).
  if (s.has_damage() &&
      (s.damage().model() == v1::NONE || s.damage().model() == v1::DAMAGE_MODEL_UNSPECIFIED))
    s.clear_damage();
  if (s.has_damage()) {
    auto* d = s.mutable_damage();
    if (!d->has_length()) d->set_length(kDamageLength);
    if (!d->has_epsilon_f()) d->set_epsilon_f(kEpsilonF);
    if (!d->has_fracture_energy()) d->set_fracture_energy(kFractureEnergy);
    if (!d->has_zeta()) d->set_zeta(kZeta);
    if (!d->has_update_every()) d->set_update_every(kDamageUpdateEvery);
    if (d->linear_solver() == v1::DAMAGE_LINEAR_SOLVER_UNSPECIFIED) d->set_linear_solver(v1::AUTO);
  }
  return s;
}

void validate_spec(const v1::RunSpec& s, const SpecLimits& limits) {
  const auto& g = s.geometry();
  switch (g.shape_case()) {
    case v1::Geometry::kDisk:
      require_finite_positive(g.disk().radius(), "geometry.disk.radius");
      break;
    case v1::Geometry::kRoundedSquare: {
      const double side = g.rounded_square().side(), rc = g.rounded_square().corner_radius();
      require_finite_positive(side, "geometry.rounded_square.side");
      require(std::isfinite(rc) && rc >= 0 && rc <= 0.5 * side,
              "geometry.rounded_square.corner_radius", "must be >= 0 and <= side / 2");
      break;
    }
    case v1::Geometry::kMeshFile: {
      if (!limits.mesh_root.empty()) {
        (void)resolve_mesh_file(limits.mesh_root, g.mesh_file());  // the host's folder only
        break;
      }
      require(!g.mesh_file().empty(), "geometry.mesh_file", "must name a .msh file");
      std::error_code ec;
      require(std::filesystem::is_regular_file(g.mesh_file(), ec), "geometry.mesh_file",
              "file '" + g.mesh_file() + "' does not exist or is not a regular file");
      break;
    }
    case v1::Geometry::kCorrugatedStrip: {
      const auto& c = g.corrugated_strip();
      require_finite_positive(c.wavelength(), "geometry.corrugated_strip.wavelength");
      require_finite_positive(c.height(), "geometry.corrugated_strip.height");
      require(std::isfinite(c.amplitude()) && std::fabs(c.amplitude()) < 0.5 * c.height(),
              "geometry.corrugated_strip.amplitude",
              "must be finite with |amplitude| < height / 2");
      break;
    }
    case v1::Geometry::kCylinder: {
      const auto& c = g.cylinder();
      require_finite_positive(c.radius(), "geometry.cylinder.radius");
      require_finite_positive(c.thickness(), "geometry.cylinder.thickness");
      require(c.thickness() <= 100 * c.radius() && c.radius() <= 1000 * c.thickness(),
              "geometry.cylinder.thickness", "must be between radius / 1000 and 100 x radius");
      require(v1::FaceCondition_IsValid(c.faces()) && c.faces() != v1::FACE_CONDITION_UNSPECIFIED,
              "geometry.cylinder.faces", "must be SLIDING, BONDED or FREE");
      break;
    }
    case v1::Geometry::kCorrugatedBox: {
      const auto& b = g.corrugated_box();
      require_finite_positive(b.lx(), "geometry.corrugated_box.lx");
      require_finite_positive(b.ly(), "geometry.corrugated_box.ly");
      require_finite_positive(b.lz(), "geometry.corrugated_box.lz");
      require(std::isfinite(b.amplitude()) && std::fabs(b.amplitude()) < 0.5 * b.lz(),
              "geometry.corrugated_box.amplitude", "must be finite with |amplitude| < lz / 2");
      require(std::isfinite(b.kx()) && multiple_of_pi(b.kx() * b.lx()),
              "geometry.corrugated_box.kx",
              "must make kx lx a multiple of pi (>= 0): the sliding walls are the corrugation's "
              "symmetry planes");
      require(std::isfinite(b.ky()) && multiple_of_pi(b.ky() * b.ly()),
              "geometry.corrugated_box.ky",
              "must make ky ly a multiple of pi (>= 0): the sliding walls are the corrugation's "
              "symmetry planes");
      break;
    }
    case v1::Geometry::SHAPE_NOT_SET:
      throw SpecError("geometry",
                      "one of disk, rounded_square, mesh_file, corrugated_strip, cylinder or "
                      "corrugated_box is required");
  }
  require(v1::Mesher_IsValid(g.mesher()) && g.mesher() != v1::MESHER_UNSPECIFIED, "geometry.mesher",
          "must be FRONTAL_DELAUNAY or CONCENTRIC_RINGS");
  require(g.mesher() != v1::CONCENTRIC_RINGS || g.has_disk() || g.has_cylinder(), "geometry.mesher",
          "CONCENTRIC_RINGS meshes disks and cylinders only");
  require(std::isfinite(g.mesh_rotation()) && std::fabs(g.mesh_rotation()) <= 8.0,
          "geometry.mesh_rotation", "must be a finite angle in [-8, 8] rad");
  require(g.mesh_rotation() == 0.0 || g.has_disk() || g.has_cylinder(), "geometry.mesh_rotation",
          "applies to disks and cylinders only (it would turn any other body)");
  const auto& rough = g.rim_roughness();
  require(std::isfinite(rough.amplitude()) && rough.amplitude() >= 0 && rough.amplitude() <= 0.02,
          "geometry.rim_roughness.amplitude", "must be >= 0 and <= 0.02 (of R0)");
  require(rough.amplitude() == 0 || g.has_disk() || g.has_rounded_square() || g.has_cylinder(),
          "geometry.rim_roughness.amplitude",
          "applies to disks, rounded squares and cylinders only");
  require(rough.min_mode() >= 1 && rough.max_mode() >= rough.min_mode() && rough.max_mode() <= 1024,
          "geometry.rim_roughness", "needs 1 <= min_mode <= max_mode <= 1024");
  require(g.target_elements() >= kMinElements && g.target_elements() <= limits.max_elements,
          "geometry.target_elements",
          "must be between " + std::to_string(kMinElements) + " and " +
              std::to_string(limits.max_elements));

  const auto& m = s.material();
  require_finite_positive(m.density(), "material.density");
  require_finite_positive(m.bulk_modulus(), "material.bulk_modulus");
  require(std::isfinite(m.shear_modulus()) && m.shear_modulus() >= 0, "material.shear_modulus",
          "must be a finite number >= 0");
  require_finite_positive(m.tait_gamma(), "material.tait_gamma");
  require(std::isfinite(m.shear_viscosity()) && m.shear_viscosity() >= 0,
          "material.shear_viscosity", "must be a finite number >= 0 (Pa s)");

  const auto& v = s.viscosity();
  require(std::isfinite(v.c1()) && v.c1() >= 0, "viscosity.c1", "must be a finite number >= 0");
  require(std::isfinite(v.c2()) && v.c2() >= 0, "viscosity.c2", "must be a finite number >= 0");
  require(v1::ViscosityActivation_IsValid(v.activation()) &&
              v.activation() != v1::VISCOSITY_ACTIVATION_UNSPECIFIED,
          "viscosity.activation", "must be CONTINUOUS or COMPRESSION_ONLY");
  require(std::isfinite(v.ramp()) && v.ramp() > 0 && v.ramp() <= 10, "viscosity.ramp",
          "must be > 0 and <= 10");
  const auto& el = s.element();
  require(v1::ElementFormulation_IsValid(el.formulation()) &&
              el.formulation() != v1::ELEMENT_FORMULATION_UNSPECIFIED,
          "element.formulation", "must be P1 or AVERAGE_NODAL_PRESSURE");
  require(
      std::isfinite(el.element_weight()) && el.element_weight() >= 0 && el.element_weight() <= 1,
      "element.element_weight", "must be between 0 and 1");
  require(std::isfinite(el.stabilization()) && el.stabilization() >= 0 && el.stabilization() <= 10,
          "element.stabilization", "must be between 0 and 10");
  require(std::isfinite(el.mass_blend()) && el.mass_blend() >= 0 && el.mass_blend() <= 1,
          "element.mass_blend", "must be between 0 (lumped) and 1 (consistent)");

  const auto& l = s.load();
  require(
      std::isfinite(l.pressure()) && l.pressure() >= 0 && l.pressure() <= 100 * m.bulk_modulus(),
      "load.pressure", "must be a finite number >= 0 and <= 100 x material.bulk_modulus");
  require_finite_positive(l.duration(), "load.duration");
  require(v1::PulseShape_IsValid(l.shape()) && l.shape() != v1::PULSE_SHAPE_UNSPECIFIED,
          "load.shape", "must be SQUARE, GAUSSIAN, LINEAR or QUADRATIC");
  require(l.perturbation().mode() >= 0 && l.perturbation().mode() <= 1024, "load.perturbation.mode",
          "must be between 0 and 1024");
  require(
      std::isfinite(l.perturbation().amplitude()) && std::fabs(l.perturbation().amplitude()) <= 1,
      "load.perturbation.amplitude", "must be between -1 and 1");

  const auto& r = s.run();
  require(std::isfinite(r.end_time()) && r.end_time() > 0 && r.end_time() <= limits.max_end_time_s,
          "run.end_time", "must be > 0 and <= " + fmt(limits.max_end_time_s) + " s");
  require(std::isfinite(r.cfl()) && r.cfl() > 0 && r.cfl() < 1, "run.cfl", "must be > 0 and < 1");
  require(std::isfinite(r.output_interval()) && r.output_interval() >= 0, "run.output_interval",
          "must be >= 0 (0 = no field frames)");
  require(r.output_interval() == 0 || r.end_time() / r.output_interval() <= limits.max_frames,
          "run.output_interval",
          "gives more than " + std::to_string(limits.max_frames) + " frames");
  require_finite_positive(r.history_interval(), "run.history_interval");
  require(r.end_time() / r.history_interval() <= static_cast<double>(limits.max_history_samples),
          "run.history_interval",
          "gives more than " + std::to_string(limits.max_history_samples) + " samples");
  require(r.modes() >= 0 && r.modes() <= limits.max_modes, "run.modes",
          "must be between 0 and " + std::to_string(limits.max_modes));
  require(r.threads() >= 1 && r.threads() <= limits.max_threads, "run.threads",
          "must be between 1 and " + std::to_string(limits.max_threads));
  require(r.max_aspect_ratio() == 0 || (std::isfinite(r.max_aspect_ratio()) &&
                                        r.max_aspect_ratio() > kEquilateralAspectRatio),
          "run.max_aspect_ratio", "must be 0 (no limit) or > 1.1547 (an equilateral triangle's)");

  if (s.has_damage()) {
    const auto& d = s.damage();
    require(v1::DamageModel_IsValid(d.model()) && d.model() != v1::DAMAGE_MODEL_UNSPECIFIED,
            "damage.model", "must be NONE, TALAMINI or GIOVANARDI");
    require_finite_positive(d.length(), "damage.length");
    require_finite_positive(d.epsilon_f(), "damage.epsilon_f");
    require_finite_positive(d.fracture_energy(), "damage.fracture_energy");
    require(std::isfinite(d.zeta()) && d.zeta() >= 0, "damage.zeta",
            "must be a finite number >= 0 (Pa s)");
    require(d.update_every() >= 1 && d.update_every() <= 10000, "damage.update_every",
            "must be between 1 and 10000 (mechanical steps)");
    require(v1::DamageLinearSolver_IsValid(d.linear_solver()) &&
                d.linear_solver() != v1::DAMAGE_LINEAR_SOLVER_UNSPECIFIED,
            "damage.linear_solver", "must be AUTO, DIRECT or ITERATIVE");
  }
}

v1::RunSpec normalize_spec(const v1::RunSpec& spec, const SpecLimits& limits) {
  v1::RunSpec s = with_defaults(spec);
  validate_spec(s, limits);
  return s;
}

std::string spec_to_json(const v1::RunSpec& spec) {
  std::string out;
  pb::util::JsonPrintOptions options;
  options.preserve_proto_field_names = true;
  (void)pb::util::MessageToJsonString(spec, &out, options);
  return out;
}

namespace {

Mesh mesh_geometry(const v1::Geometry& g, const SpecLimits& limits) {
  switch (g.shape_case()) {
    case v1::Geometry::kDisk: {
      Mesh mesh = g.mesher() == v1::CONCENTRIC_RINGS
                      ? mesh_disk_rings(g.disk().radius(), g.target_elements())
                      : mesh_disk(g.disk().radius(), g.target_elements());
      if (g.mesh_rotation() != 0.0) rotate_mesh(mesh, g.mesh_rotation());
      return mesh;
    }
    case v1::Geometry::kCorrugatedStrip: {
      const auto& c = g.corrugated_strip();
      return make_corrugated_strip_mesh(c.wavelength(), c.height(), c.amplitude(),
                                        g.target_elements());
    }
    case v1::Geometry::kRoundedSquare:
      return mesh_rounded_square(g.rounded_square().side(), g.rounded_square().corner_radius(),
                                 g.target_elements());
    case v1::Geometry::kCylinder: {
      const auto& c = g.cylinder();
      Mesh mesh = g.mesher() == v1::CONCENTRIC_RINGS
                      ? mesh_cylinder_rings(c.radius(), c.thickness(), g.target_elements())
                      : mesh_cylinder(c.radius(), c.thickness(), g.target_elements());
      if (g.mesh_rotation() != 0.0) rotate_mesh(mesh, g.mesh_rotation());  // about the z axis
      return mesh;
    }
    case v1::Geometry::kCorrugatedBox: {
      const auto& b = g.corrugated_box();
      return make_corrugated_box_mesh(b.lx(), b.ly(), b.lz(), b.amplitude(), b.kx(), b.ky(),
                                      g.target_elements());
    }
    case v1::Geometry::kMeshFile: {
      const std::string path = limits.mesh_root.empty()
                                   ? g.mesh_file()
                                   : resolve_mesh_file(limits.mesh_root, g.mesh_file());
      try {
        return read_gmsh_file(path);
      } catch (const std::exception& e) {
        // Name the file as the spec does: a host's own folders stay out of the message.
        std::string message = e.what();
        for (auto at = message.find(path); at != std::string::npos && path != g.mesh_file();
             at = message.find(path, at + g.mesh_file().size())) {
          message.replace(at, path.size(), g.mesh_file());
        }
        throw SpecError("geometry.mesh_file", message);
      }
    }
    case v1::Geometry::SHAPE_NOT_SET:
      break;
  }
  throw SpecError("geometry",
                  "one of disk, rounded_square, mesh_file, corrugated_strip, cylinder or "
                  "corrugated_box is required");
}

}  // namespace

bool meshes_with_gmsh(const v1::Geometry& g) {
  switch (g.shape_case()) {
    case v1::Geometry::kDisk:
      return g.mesher() != v1::CONCENTRIC_RINGS;
    case v1::Geometry::kCylinder:
      return g.mesher() != v1::CONCENTRIC_RINGS;
    case v1::Geometry::kRoundedSquare:
    case v1::Geometry::kMeshFile:
      return true;
    default:
      return false;
  }
}

namespace {

void require_element_limit(const Mesh& mesh, const SpecLimits& limits) {
  require(static_cast<int64_t>(mesh.element_count()) <= limits.max_elements,
          "geometry.target_elements",
          "the mesh has " + std::to_string(mesh.element_count()) + " elements, more than " +
              std::to_string(limits.max_elements));
}

}  // namespace

Mesh smooth_mesh(const v1::Geometry& g, const SpecLimits& limits, const MeshCache* cache,
                 MeshingReport* report) {
  const auto started = std::chrono::steady_clock::now();
  const auto material = cache ? mesh_key_material(g) : std::nullopt;
  MeshCacheOutcome outcome = MeshCacheOutcome::kNotUsed;
  std::string warning;
  Mesh mesh = material ? cache->get_or_build(
                             mesh_cache_key(*material), *material,
                             [&] { return mesh_geometry(g, limits); }, &outcome, &warning)
                       : mesh_geometry(g, limits);
  if (report) {
    report->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    report->cache = outcome;
    report->warning = warning;
  }
  require_element_limit(mesh, limits);
  return mesh;
}

Problem make_problem_with_mesh(const v1::RunSpec& s, Mesh mesh, const SpecLimits& limits) {
  Problem p;
  p.mesh = std::move(mesh);
  const auto& g = s.geometry();
  switch (g.shape_case()) {
    case v1::Geometry::kDisk:
      p.origin = {0.0, 0.0};
      p.reference_radius_m = g.disk().radius();
      break;
    case v1::Geometry::kRoundedSquare:
      p.origin = {0.0, 0.0};
      p.reference_radius_m = 0.5 * g.rounded_square().side();
      break;
    case v1::Geometry::kCorrugatedStrip:
      set_up_corrugated_strip(g, p);
      break;
    case v1::Geometry::kCylinder:
      set_up_cylinder(g, p);
      break;
    case v1::Geometry::kCorrugatedBox:
      set_up_corrugated_box(g, p);
      break;
    default:
      break;
  }
  // The roughness moves nodes of the (possibly cached) smooth mesh, so it is applied here.
  if (g.rim_roughness().amplitude() > 0) {
    const auto& r = g.rim_roughness();
    apply_rim_roughness(p.mesh, p.origin, p.reference_radius_m,
                        {r.amplitude(), r.min_mode(), r.max_mode(), r.seed()});
  }
  require_element_limit(p.mesh, limits);
  set_parameters(s, p);
  return p;
}

Problem make_problem(const v1::RunSpec& s, const SpecLimits& limits, const MeshCache* cache,
                     MeshingReport* report) {
  return make_problem_with_mesh(s, smooth_mesh(s.geometry(), limits, cache, report), limits);
}

NondimensionalGroups spec_groups(const v1::RunSpec& s) {
  Problem p;
  set_parameters(s, p);
  double r0 = std::nan("");
  if (s.geometry().has_disk()) r0 = s.geometry().disk().radius();
  if (s.geometry().has_rounded_square()) r0 = 0.5 * s.geometry().rounded_square().side();
  if (s.geometry().has_corrugated_strip()) r0 = s.geometry().corrugated_strip().height();
  if (s.geometry().has_cylinder()) r0 = s.geometry().cylinder().radius();
  if (s.geometry().has_corrugated_box()) r0 = s.geometry().corrugated_box().lz();
  return nondimensional_groups(p.material, p.viscosity, p.load, r0);
}

SolverOptions make_options(const v1::RunSpec& s) {
  SolverOptions o;
  const auto& r = s.run();
  o.end_time_s = r.end_time();
  o.cfl = r.cfl();
  o.output_interval_s = r.output_interval();
  o.history_interval_s = r.history_interval();
  o.modes = r.modes();
  o.threads = r.threads();
  o.max_aspect_ratio = r.max_aspect_ratio();
  return o;
}

}  // namespace softshock
